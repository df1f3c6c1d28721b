"""The one check of a number that must be finite and > 0 (or >= 0): options, library
arguments and values read from files all go through :func:`positive` / :func:`non_negative`,
so every caller refuses NaN, infinities, booleans and text that is no number alike."""

from __future__ import annotations

import math


def number(value, what: str | None = None) -> float:
    """``value`` (a number or its text) as a finite float; ValueError naming ``what`` otherwise."""
    if isinstance(value, bool):
        raise ValueError(_say(what, "a number", value))
    try:
        v = float(value)
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
    except (TypeError, ValueError):
        return False


def _say(what: str | None, expected: str, value) -> str:
    return f"{what} must be {expected}, got {value!r}" if what else f"expected {expected}, got {value!r}"
