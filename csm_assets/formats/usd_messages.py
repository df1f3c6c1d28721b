"""usd-core's diagnostics as lines a user can act on: the warnings and errors it would print
(:func:`usd_diagnostics`) and the reason in one of its exceptions (:func:`usd_reason`)."""

from __future__ import annotations

import contextlib
import re

from pxr import UsdUtils


@contextlib.contextmanager
def usd_diagnostics(messages: list[str]):
    """Collect USD's own warnings and errors (which it would print to stderr) as lines in
    ``messages`` while the block runs."""
    delegate = UsdUtils.CoalescingDiagnosticDelegate()
    try:
        yield
    finally:
        for d in delegate.TakeUncoalescedDiagnostics():
            text = " ".join(str(d.commentary).split())
            text = re.sub(r"\s*\((instantiating stage on stage|flattening stage) @[^)]*\)$", "", text)
            if text and text not in messages:
                messages.append(text)
        del delegate


_PARSE_ERROR = re.compile(r":(\d+):(\d+): (.*?)(?: at '.*?')?(?: in <(.*?)>)?\s*'?\s*$", re.S)


def usd_reason(message: str) -> str:
    """The part of a usd-core error a user can act on: for a text layer that does not parse
    ('... : '/p/x.usda:16:107: parse error matching <parser rule> at '' in </World/wall.points>'),
    'line 16, column 107 (in /World/wall.points): parse error' (the parser's rule names left out);
    else the message's last line with text in it, without Tf's 'Error in <function> at line N in
    file <source>' prefix."""
    m = _PARSE_ERROR.search(message)
    if m:
        line, col, said, site = m.groups()
        said = "parse error" if said.startswith("parse error matching") else said.strip()
        return f"line {line}, column {col}" + (f" (in {site})" if site else "") + f": {said}"
    lines = [t.strip().strip("'").strip() for t in message.splitlines()]
    last = next((t for t in reversed(lines) if any(c.isalnum() for c in t)), "")
    return re.sub(r"^Error in '[^']*' at line \d+ in file \S+ : ", "", last).strip("' ")
