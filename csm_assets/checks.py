"""The one check of a number that must be finite and > 0 (or >= 0): options, library
arguments and values read from files all go through :func:`positive` / :func:`non_negative`,
so every caller refuses NaN, infinities, booleans and text that is no number alike."""

from __future__ import annotations

import math


FLOAT32_MAX = 3.4028234663852886e38  # the largest 32-bit float: what shaders and Blender's sockets hold

def number(value, what: str | None = None) -> float:
    """``value`` (a number or its text) as a finite float; ValueError naming ``what`` otherwise."""
    if isinstance(value, bool):
        raise ValueError(_say(what, "a number", value))
    try:
        v = float(value)
    except OverflowError:  # an integer beyond float's range (JSON allows 1 followed by 400 zeros)
        raise ValueError(_say(what, "a finite number", value)) from None
    except (TypeError, ValueError):
        raise ValueError(_say(what, "a number", value)) from None
    if not math.isfinite(v):
        raise ValueError(_say(what, "a finite number", value))
    return v


def positive(value, what: str | None = None) -> float:
    """``value`` as a float, finite and > 0; ValueError naming ``what`` otherwise."""
    v = number(value, what) if not _nan_or_inf(value) else math.nan
    if not v > 0:
        raise ValueError(_say(what, "a finite number > 0", value))
    return v


def non_negative(value, what: str | None = None) -> float:
    """``value`` as a float, finite and >= 0; ValueError naming ``what`` otherwise."""
    v = number(value, what) if not _nan_or_inf(value) else math.nan
    if not v >= 0:
        raise ValueError(_say(what, "a finite number >= 0", value))
    return v


def _nan_or_inf(value) -> bool:
    try:
        return not isinstance(value, bool) and not math.isfinite(float(value))
    except OverflowError:
        return True
    except (TypeError, ValueError):
        return False


def _say(what: str | None, expected: str, value) -> str:
    shown = short_repr(value)
    return f"{what} must be {expected}, got {shown}" if what else f"expected {expected}, got {shown}"


def short_repr(value, most: int = 60) -> str:
    """``repr(value)``, its middle cut out past ``most`` characters (a 400-digit integer)."""
    try:
        text = repr(value)
    except ValueError:  # an integer past Python's digit limit
        return f"an integer of {value.bit_length()} bits"
    return text if len(text) <= most else f"{text[:most // 2]}...{text[-most // 4:]} ({len(text)} characters)"
