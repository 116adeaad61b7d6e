"""Durations (s) applied as frame counts at the frame rate seen, for the front end's per-frame rules
(the grouping's and box tracker's life cycle, the feature tracker's re-detection cadence, lost-feature
memory and KLT step): one clock rule, ``FrameClock``, and one check of the duration settings,
``check_durations``."""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from estimators.errors import ConfigError


class FrameClock:
    """Durations (s) as frame counts at the frame rate seen: the (lower) median of the last ``n``
    positive intervals between the frame times given to :meth:`tick` (never a configured rate: a
    live camera's rate varies, and a dropped frame is one long interval the median ignores).

    ``frames(d)`` = ``d`` over that median interval, rounded (halves up), at least ``lo``; before two
    intervals are seen (a live camera's first is often its start-up's), and for a duration of
    ``UNKNOWN`` frames or more, ``UNKNOWN`` (a count no track reaches: nothing is decided by time
    yet, or ever). A duration of 0 s is ``lo`` frames at every rate, so also before one is seen
    (``redetect_s`` 0: every frame from the first)."""

    UNKNOWN = 2**31

    def __init__(self, n: int = 15) -> None:
        self._dt: deque[float] = deque(maxlen=n)
        self._last: float | None = None
        self.period_s: float | None = None

    def tick(self, t_s: float) -> float:
        """One frame at time t_s (s); returns the time since the frame before (0.0 for the first)."""
        t = float(t_s)
        dt = t - self._last if self._last is not None else 0.0
        if self._last is not None and t > self._last:
            self._dt.append(t - self._last)
            if len(self._dt) >= 2:  # (one interval is no rate yet: a live camera's first is
                # often its start-up's; of an even count the lower median: a long interval then
                # makes counts too large, deciding nothing early, never too small)
                self.period_s = sorted(self._dt)[(len(self._dt) - 1) // 2]
        self._last = t
        return dt

    def frames(self, d_s: float, lo: int = 1) -> int:
        """The frame count of a duration d_s (s) at the rate seen, at least ``lo``."""
        if d_s <= 0:  # (0 frames at any rate: no rate needed)
            return lo
        if self.period_s is None:
            return self.UNKNOWN
        n = d_s / self.period_s
        if not n < self.UNKNOWN:  # (a duration no run reaches, e.g. 1e308 s: no overflow to int)
            return self.UNKNOWN
        return max(lo, math.floor(n + 0.5))


def check_durations(
    owner: str, renamed: dict[str, tuple[str, str]], old: dict, given: dict
) -> dict[str, float]:
    """Check a tracker's duration settings (s): ``given`` {key: value}, each a finite number >= 0;
    ``old`` the keywords it does not take: a renamed frame count (``renamed``: old key -> (new key,
    its default in frames at 30 fps)) is an error naming its replacement, anything else the usual
    TypeError."""
    for k in old:
        if k in renamed:
            raise ConfigError(f"{owner}: {renamed_text(renamed, k)}")
    if old:
        raise TypeError(f"{owner}.__init__() got an unexpected keyword argument {next(iter(old))!r}")
    out = {}
    for k, v in given.items():
        real = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
        if not real or not 0 <= v < math.inf:
            raise ConfigError(f"{owner}: expected {k} a finite duration >= 0 (seconds); got {v!r}")
        out[k] = float(v)
    return out


def renamed_text(renamed: dict[str, tuple[str, str]], key: str, where: str = "") -> str:
    """What is said of ``key``, a frame count that ``renamed`` (old key -> (new key, its default in frames
    at 30 fps)) replaced by a duration: it names the replacement. ``where``: the key's place, as the
    front end's option check names it (``" in grouping"``), or nothing (the class's own check, its name
    before the message)."""
    new, hint = renamed[key]
    return (f"'{key}'{where} (frames) was replaced by '{new}' (seconds, applied at the frame rate seen: "
            f"{hint}); set {new} instead")
