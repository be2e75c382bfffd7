"""Time, exactly: the one rule for block boundaries and for which frames lie inside them,
and the documented size limits.

Block times are resolved once, when a score is loaded (:func:`exact_time`: absolute times
rounded to the microsecond, so ``1.0 + 1.4`` is the same time as ``2.4``). Frame ``k`` is at
``k / fps`` [s]; frames ``first_frame(start) <= k < first_frame(end)`` lie inside
``[start, end)`` (:func:`frame_range`). The scheduler, the residuals, the report and
``check`` all use this rule, so a block shifted by any multiple of the frame period covers
the same frames, shifted.

Limits (exceeding one is a clean error, never a MemoryError or a hang):

* :data:`MAX_DURATION` seconds of score (1 hour);
* :data:`MAX_FRAMES` frames per rollout (1 hour at 50 fps);
* fps in ``[MIN_FPS, MAX_FPS]`` and finite.

Units: seconds.
"""

from __future__ import annotations

import math

from azee_mj.errors import AzeeError

#: Times are resolved to this step [s] (one microsecond).
TIME_STEP = 1e-6
_PER_SECOND = 1_000_000  # steps per second: k / 1e6 is the correctly rounded time
#: Longest score [s].
MAX_DURATION = 3600.0
#: Most frames in one rollout (1 hour at 50 fps, first and last frame included).
MAX_FRAMES = 180_001
#: Frame rate of a realized rollout unless one is given [frames/s].
DEFAULT_FPS = 50.0
#: Frame rates accepted [frames/s].
MIN_FPS, MAX_FPS = 1.0, 1000.0
#: A frame this close (in frames) to a boundary is on it.
_FRAME_SLACK = 1e-6


def exact_time(t: float) -> float:
    """``t`` [s] rounded to :data:`TIME_STEP` (the one place absolute block times are made)."""
    return round(t * _PER_SECOND) / _PER_SECOND


def root_span(start: float, end: float) -> tuple[float, float]:
    """Absolute ``(start, end)`` [s] of the root block written from ``start`` to ``end``: it
    starts at 0."""
    return 0.0, exact_time(end - start)


def child_span(
    start: float, end: float, parent_start: float, parent_end: float | None
) -> tuple[float, float]:
    """Absolute ``(start, end)`` [s] of a block written from ``start`` to ``end`` relative to
    its parent's absolute ``parent_start``: on the :data:`TIME_STEP` grid and kept within
    ``[parent_start, parent_end]`` (no upper bound if ``parent_end`` is None)."""
    lo, hi = parent_start, parent_end if parent_end is not None else math.inf
    return (
        min(max(exact_time(parent_start + start), lo), hi),
        min(max(exact_time(parent_start + end), lo), hi),
    )


def first_frame(t: float, fps: float) -> int:
    """Index of the first frame at or after time ``t`` [s] (a frame within 1e-6 frame of
    ``t`` counts as at ``t``)."""
    return max(0, math.ceil(t * fps - _FRAME_SLACK))


def frame_range(start: float, end: float, fps: float, frames: int) -> range:
    """Frame indices inside ``[start, end)`` [s] among ``frames`` frames at ``fps``."""
    return range(min(first_frame(start, fps), frames), min(first_frame(end, fps), frames))


def frame_count(duration: float, fps: float) -> int:
    """Frames of a rollout of ``duration`` [s] at ``fps``: frame 0 at 0 s to the last at or
    before the end; raises :class:`AzeeError` beyond :data:`MAX_FRAMES`."""
    n = math.floor(duration * fps + _FRAME_SLACK) + 1
    if n > MAX_FRAMES:
        raise AzeeError(
            f"{duration:g} s at {fps:g} fps is {n} frames; the limit is "
            f"{MAX_FRAMES} frames (1 hour at 50 fps): lower --fps or split the score"
        )
    return n


def check_fps(fps, option: str = "--fps") -> float:
    """``fps`` as a float if it is finite and within ``[MIN_FPS, MAX_FPS]``; else a clean
    :class:`AzeeError` naming ``option``."""
    try:
        x = float(fps)
    except (TypeError, ValueError, OverflowError):
        x = math.nan
    if not (math.isfinite(x) and MIN_FPS <= x <= MAX_FPS):
        shown = f"{fps:g}" if isinstance(fps, float) else repr(fps)
        raise AzeeError(f"{option} must be a number from {MIN_FPS:g} to {MAX_FPS:g}, got {shown}")
    return x
