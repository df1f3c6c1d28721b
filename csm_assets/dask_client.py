"""A Dask cluster as a ``concurrent.futures`` executor: ``convert --scheduler`` runs scenes on it,
``stepmap --scheduler`` the bands of one map's cone search (:mod:`csm_assets.cones.remote`)."""

from __future__ import annotations

import contextlib
import socket


def _reachable(address: str, timeout: float = 10.0) -> None:
    """ValueError naming ``address`` at once when a ``tcp://host:port`` scheduler refuses or
    does not answer a connection (Dask's client would retry for 30 s first)."""
    scheme, sep, rest = address.partition("://")
    if not sep or scheme.lower() != "tcp":
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


@contextlib.contextmanager
def dask_executor(address: str):
    """A ``concurrent.futures`` executor on the Dask scheduler at ``address``, for a ``with``.

    Args:
        address: the scheduler's ``host:port`` (or ``tcp://...``).

    Yields:
        The client's executor; the client closes after the ``with``.

    Raises:
        ValueError: Dask is not installed, or the scheduler cannot be reached.
    """
    try:
        from distributed import Client
    except ImportError as e:
        raise ValueError("--scheduler needs Dask: pip install 'csm-assets[dask]'") from e
    _reachable(address)
    try:
        client = Client(address, timeout="30s")
    except OSError as e:
        raise ValueError(f"--scheduler {address}: cannot reach the Dask scheduler ({e})") from e
    try:
        yield client.get_executor()
    finally:
        client.close()
