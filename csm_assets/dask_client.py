"""A Dask cluster as a ``concurrent.futures`` executor: ``convert --scheduler`` runs scenes on it,
``stepmap --scheduler`` the bands of one map's cone search (:mod:`csm_assets.cones.remote`)."""

from __future__ import annotations

import contextlib
import socket
import threading

ANSWER_SECONDS = 30.0  # a scheduler that takes a connection must answer within this


def _reachable(address: str, timeout: float = 10.0) -> None:
    """ValueError naming ``address`` at once when a ``tcp://host:port`` scheduler refuses or
    does not answer a connection (Dask's client would retry for 30 s first)."""
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address  # Dask reads HOST:PORT as tcp
    if scheme.lower() != "tcp":
        return  # other transports (tls, inproc, ucx): Dask says what is wrong
    host, _, port = rest.rstrip("/").rpartition(":")
    try:
        number = int(port)
    except ValueError:
        raise ValueError(f"--scheduler {address}: expected tcp://HOST:PORT") from None
    try:
        socket.create_connection((host.strip("[]") or "127.0.0.1", number), timeout=timeout).close()
    except (OSError, OverflowError) as e:
        why = getattr(e, "strerror", None) or str(e) or type(e).__name__
        raise ValueError(f"--scheduler {address}: cannot reach the Dask scheduler there ({why})") from None


def _client(Client, address: str):
    """A Client of the scheduler at ``address``; ValueError naming it when it refuses, or when it
    takes the connection but has not answered within :data:`ANSWER_SECONDS` (not a Dask scheduler, or
    a stuck one: Dask's own timeout does not bound that wait, so the client is made in a thread)."""
    made: list = []

    def connect():
        try:
            made.append(Client(address, timeout=f"{ANSWER_SECONDS}s"))
        except BaseException as e:  # noqa: BLE001 (handed to the caller's thread below)
            made.append(e)

    thread = threading.Thread(target=connect, name="csm-dask-connect", daemon=True)
    thread.start()
    thread.join(ANSWER_SECONDS + 5)
    if not made:
        raise ValueError(f"--scheduler {address}: no Dask scheduler answered there within {ANSWER_SECONDS:g} s "
                         "(the port takes connections but says nothing)")
    if isinstance(made[0], OSError):
        raise ValueError(f"--scheduler {address}: cannot reach the Dask scheduler ({made[0]})") from made[0]
    if isinstance(made[0], (ValueError, TypeError)):  # an address Dask cannot parse
        raise ValueError(f"--scheduler {address}: {made[0]}") from made[0]
    if isinstance(made[0], BaseException):
        raise made[0]
    return made[0]


@contextlib.contextmanager
def dask_executor(address: str):
    """A ``concurrent.futures`` executor on the Dask scheduler at ``address``, for a ``with``.

    Args:
        address: the scheduler's ``host:port`` (or ``tcp://...``).

    Yields:
        The client's executor; the client closes after the ``with``.

    Raises:
        ValueError: Dask is not installed, or the scheduler cannot be reached or does not answer
            (within about 45 s in all).
    """
    try:
        from distributed import Client
    except ImportError as e:
        raise ValueError("--scheduler needs Dask: pip install 'csm-assets[dask]'") from e
    _reachable(address)
    client = _client(Client, address)
    try:
        yield client.get_executor()
    finally:
        client.close()
