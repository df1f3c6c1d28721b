"""How freshness compares files: sha256 of their content, text scene files with line endings normalised
(a ``core.autocrlf=true`` checkout and one without agree)."""

from __future__ import annotations

import hashlib
from pathlib import Path

TEXT_SUFFIXES = (".gltf", ".obj", ".mtl", ".usda", ".glslfx", ".glsl")  # hashed with line endings normalised


def file_hash(path) -> str:
    """sha256 of a file, as freshness compares files.

    A text scene file (:data:`TEXT_SUFFIXES`) is hashed with every CRLF read as LF, so that a
    checkout with ``core.autocrlf=true`` (Windows) and one without agree; binary files as they
    are.

    Args:
        path: the file (OSError when unreadable).

    Returns:
        The hex digest.
    """
    h = hashlib.sha256()
    text = Path(path).suffix.lower() in TEXT_SUFFIXES
    with open(path, "rb") as f:
        carry = b""
        for block in iter(lambda: f.read(1 << 20), b""):
            if text:
                block = carry + block
                carry = block[-1:] if block.endswith(b"\r") else b""  # a CRLF split across blocks
                block = (block[:-1] if carry else block).replace(b"\r\n", b"\n")
            h.update(block)
        h.update(carry)
    return h.hexdigest()


def content_hash(data: bytes, name: str) -> str:
    """:func:`file_hash` of ``data`` as if it were a file named ``name``."""
    if Path(name).suffix.lower() in TEXT_SUFFIXES:
        data = bytes(data).replace(b"\r\n", b"\n")
    return hashlib.sha256(data).hexdigest()
