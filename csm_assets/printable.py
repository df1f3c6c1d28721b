"""Text from files made safe to print: one terminal line, no control characters.

Names and uris come from the files a user converts (a material name, a texture uri) and
can hold a newline, a carriage return or a terminal escape: printed raw, one warning
could become two lines, one of them a forged ``csm-assets: error:``, or rewrite the
terminal. :func:`printable` escapes them as Python does in a repr (``\\n``, ``\\x1b``,
``\\u2028``), so every message stays one line and shows what the file holds.
"""

from __future__ import annotations

import re

# C0 and C1 controls, DEL, the Unicode line/paragraph separators and the bidi overrides
_CONTROLS = re.compile("[\x00-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069]")
_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def _escape(m: re.Match) -> str:
    ch = m.group()
    return _NAMED.get(ch) or (f"\\x{ord(ch):02x}" if ord(ch) < 0x100 else f"\\u{ord(ch):04x}")


def printable(text) -> str:
    """``text`` (any object, as str) with every control character escaped."""
    return _CONTROLS.sub(_escape, str(text))
