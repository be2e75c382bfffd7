"""How fast a hand goes along the path of one movement: a single minimum-jerk bell, slowed
in its curves by the two-thirds power law.

A movement's frames (its posture at each frame, from one hold to the next) fix a path;
solving them one by one (a transpath's points, a blend pushed out of the body, two tracks
timed differently) can leave stalls and surges along it: several speed peaks. Pacing keeps
the path and the movement's start and end times and chooses when each point of the path
is reached:

- the hand's distance along its path (the summed arc length of its sites) follows the
  minimum-jerk profile over the movement's time (Flash and Hogan 1985): one bell-shaped
  speed profile, at rest at both ends;
- in a curve the distance counts more, by curvature^(1/3) (curvatures under
  :data:`STRAIGHT` count as straight), so speed ~ curvature^(-1/3) there (the two-thirds
  power law, Lacquaniti, Terzuolo and Viviani 1983) and a sharp turn slows to nearly a
  stop, as a hand does.

Pure functions of sampled positions (no model). Units: metres, seconds.
"""

from __future__ import annotations

import numpy as np

from azee_mj.blend import minjerk

#: Curvature [1/m] under which a path counts as straight (a radius of 0.5 m or more).
STRAIGHT = 2.0
#: Largest curvature [1/m] pacing heeds (a radius of 2 mm: a reversal).
SHARPEST = 500.0
#: The power law's exponent on curvature of the distance weight (speed ~ curvature^-1/3).
BETA = 1.0 / 3.0
#: Samples along the path where the distance weight is integrated.
SAMPLES = 128
#: Smoothing passes over a movement's path of postures (:func:`smoothed`).
SMOOTHING = 4
#: How much a joint's turn counts as distance along a path [m/rad]: enough that a joint
#: turning while the sites stand nearly still (a hand turning about its wrist) is not
#: rushed through in a frame or two.
LEVER = 0.02
#: A movement shorter than this [m] (summed over its sites) is left as it is.
SHORTEST = 2e-3


def turning(x: np.ndarray) -> np.ndarray:
    """(n,) curvature [1/m] of the polyline ``x`` (n, 3) at each point: that of the circle
    through it and its two neighbours (0 where two of them coincide; the ends take their
    neighbour's)."""
    a, b = x[1:-1] - x[:-2], x[2:] - x[1:-1]
    la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, x[2:] - x[:-2]))
    cross = np.linalg.norm(np.cross(a, b), axis=1)
    den = la * lb * lc
    k = np.where(den > 1e-12, 2.0 * cross / np.maximum(den, 1e-300), 0.0)
    return np.r_[k[:1], k, k[-1:]] if len(k) else np.zeros(len(x))


def distance_weight(curve: np.ndarray, s: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """(M,) how much a unit of path counts at each parameter of ``grid`` (M,) on a path
    whose frames are at parameters ``s`` (n,) (increasing) and whose curved point is at
    ``curve`` (n, 3) at each frame: (curvature / STRAIGHT)^BETA in curves, 1 where
    straight (the curvature of ``curve`` at its frames, :func:`turning`)."""
    k = np.interp(grid, s, turning(np.asarray(curve, float)))
    k = np.convolve(np.pad(k, 2, mode="edge"), np.ones(5) / 5, mode="valid")  # sample noise
    return (np.clip(k, STRAIGHT, SHARPEST) / STRAIGHT) ** BETA


def paced(
    points: np.ndarray,
    curve: np.ndarray | None = None,
    joints: np.ndarray | None = None,
    pins=(),
) -> np.ndarray | None:
    """(n,) the fractional frame of a path to show at each of its n evenly timed frames
    (from a rest to a rest), so that the summed distance its sites travel (``points``
    (n, k, 3), k sites) follows one minimum-jerk bell; with ``curve`` (n, 3) (the point
    tracing a curved path), that distance counts more where ``curve`` bends (the
    two-thirds power law). ``joints`` (n, d): the joint values of the path [rad], whose
    changes count too (:data:`LEVER` metres a radian), so that a joint that turns where
    the sites hardly move (a hand turning about its wrist) is not rushed. ``pins``: inner
    frames that keep their time (where a transpath starts or ends), the bell bent
    smoothly to meet them. None when the sites hardly move, or the bell cannot meet the
    pins going forward."""
    points = np.asarray(points, float)
    n = len(points)
    if n < 3:
        return None
    step = np.linalg.norm(np.diff(points, axis=0), axis=2).sum(axis=1)  # (n-1,)
    total = float(step.sum())
    if joints is not None:
        step = step + LEVER * np.linalg.norm(np.diff(joints, axis=0), axis=1)
    if total < SHORTEST:
        return None
    # strictly increasing (a stalled frame adds nothing to the distance)
    s = np.r_[0.0, np.cumsum(step)] + np.arange(n) * total * 1e-9
    grid = np.linspace(s[0], s[-1], SAMPLES)
    w = np.ones(SAMPLES) if curve is None else distance_weight(np.asarray(curve), s, grid)
    sigma = np.r_[0.0, np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(grid))]
    u = np.linspace(0.0, 1.0, n)
    target = sigma[-1] * minjerk(u)
    pins = sorted(p for p in set(pins) if 1 < p < n - 2)  # next to an end: the end
    if pins:
        from scipy.interpolate import PchipInterpolator  # here: 50 MB a realization may not need

        miss = np.interp(s[pins], grid, sigma) - target[pins]
        target = target + PchipInterpolator(np.r_[0.0, u[pins], 1.0], np.r_[0.0, miss, 0.0])(u)
        if np.any(np.diff(target) < 0.0):
            return None
    at = np.interp(target, sigma, grid)
    out = np.interp(at, s, np.arange(n, dtype=float))
    out[0], out[-1] = 0.0, n - 1.0
    return out


def smoothed(q: np.ndarray, passes: int = SMOOTHING) -> np.ndarray:
    """Rows of ``q`` (n, d) (a path of postures) with their kinks and single-frame spikes
    smoothed out: ``passes`` of moving each inner row half way to the mean of its
    neighbours, the first and last rows kept."""
    q = np.array(q, float)
    for _ in range(passes):
        q[1:-1] += 0.25 * (q[:-2] + q[2:] - 2.0 * q[1:-1])
    return q


def resample(q: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Rows of ``q`` (n, d) at fractional ``frames`` (m,), linearly interpolated."""
    lo = np.clip(np.floor(frames).astype(int), 0, len(q) - 2)
    w = (frames - lo)[:, None]
    return q[lo] * (1.0 - w) + q[lo + 1] * w
