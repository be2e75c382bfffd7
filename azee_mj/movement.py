"""How a hand moves: smoothness and speed measures of a trajectory, and its movements.

Pure functions of sampled positions (no model, no files). The measures are the ones motor
control uses to compare movements without motion capture:

- **SPARC** (spectral arc length; Balasubramanian, Melendez-Calderon, Roby-Brami and Burdet
  2015, J. NeuroEng. Rehabil. 12:112): the arc length of the normalised Fourier magnitude
  spectrum of the speed profile, up to an adaptive cut-off. Minimum jerk gives -1.40 at any
  size and duration; less smooth movements are more negative.
- **LDLJ** (log dimensionless jerk, same paper, velocity-based): ``-ln(T^3 / v_peak^2 *
  integral |d^2 v / dt^2|^2 dt)``; minimum jerk gives -5.32.
- **speed peaks**: local maxima of the speed profile standing out by at least
  :data:`PEAK_PROMINENCE` of the movement's peak speed; a reach has one.
- **two-thirds power law** (Lacquaniti, Terzuolo and Viviani 1983): on curved paths speed
  is proportional to curvature^beta with beta = -1/3; :func:`power_law_exponent` fits beta.

Units: metres, seconds; speeds m/s.
"""

from __future__ import annotations

import dataclasses

import numpy as np

#: Minimum-jerk speed peak over mean speed: a rest-to-rest reach of distance D in time T
#: peaks at ``MINJERK_PEAK * D / T`` (Flash and Hogan 1985).
MINJERK_PEAK = 15.0 / 8.0
#: A speed peak counts when it stands out by this fraction of the movement's peak speed.
PEAK_PROMINENCE = 0.05
#: A hand moves when its speed exceeds this [m/s] (and :data:`MOVING_FRACTION` of the
#: rollout's peak); a pause shorter than :data:`MERGE_GAP` [s] does not end a movement.
MOVING_SPEED = 0.05
MOVING_FRACTION = 0.05
MERGE_GAP = 0.12


def speed(pos: np.ndarray, fs: float) -> np.ndarray:
    """(T,) speed [m/s] of positions ``pos`` (T, 3) sampled at ``fs`` [Hz] (central
    differences, one-sided at the ends)."""
    pos = np.asarray(pos, float)
    if len(pos) < 2:
        return np.zeros(len(pos))
    return np.linalg.norm(np.gradient(pos, 1.0 / fs, axis=0), axis=1)


def sparc(sp: np.ndarray, fs: float, pad_level: int = 4, fc: float = 10.0, amp_th: float = 0.05):
    """SPARC of speed profile ``sp`` (T,) sampled at ``fs`` [Hz]: the published algorithm
    (zero padding to ``2**(ceil(log2 T) + pad_level)`` points, spectrum normalised by its
    DC value, cut off at ``fc`` [Hz] or where the spectrum last exceeds ``amp_th``)."""
    sp = np.asarray(sp, float)
    nfft = int(2 ** (np.ceil(np.log2(len(sp))) + pad_level))
    f = np.arange(0, fs, fs / nfft)
    mag = np.abs(np.fft.fft(sp, nfft))
    mag = mag / mag.max()
    sel = f <= fc
    f, mag = f[sel], mag[sel]
    above = np.flatnonzero(mag >= amp_th)
    f, mag = f[above[0] : above[-1] + 1], mag[above[0] : above[-1] + 1]
    df = np.diff(f) / (f[-1] - f[0])
    return float(-np.sum(np.sqrt(df**2 + np.diff(mag) ** 2)))


def ldlj(pos: np.ndarray, fs: float) -> float:
    """Log dimensionless jerk (velocity-based) of positions ``pos`` (T, 3) at ``fs`` [Hz]."""
    dt = 1.0 / fs
    vel = np.gradient(np.asarray(pos, float), dt, axis=0)
    jerk = np.gradient(np.gradient(vel, dt, axis=0), dt, axis=0)
    duration = (len(pos) - 1) * dt
    vpeak = np.linalg.norm(vel, axis=1).max()
    if vpeak <= 0.0 or duration <= 0.0:
        return float("nan")
    integral = np.trapezoid((jerk**2).sum(axis=1), dx=dt)
    return float(-np.log(duration**3 / vpeak**2 * integral))


def speed_peaks(sp: np.ndarray) -> int:
    """How many speed peaks of ``sp`` stand out by :data:`PEAK_PROMINENCE` of its maximum.

    What ``scipy.signal.find_peaks(..., prominence=...)`` counts (a flat top is one peak;
    a peak's prominence is its height over the higher of the lowest points between it and
    a higher point on either side), written out: the realizer asks it of every bent
    movement, and importing ``scipy.signal`` costs a process 70 MB."""
    sp = np.asarray(sp, float)
    if sp.size < 3 or sp.max() <= 0.0:
        return int(sp.size > 0 and sp.max() > 0.0)
    x = np.r_[0.0, sp, 0.0].tolist()  # a peak at either end still counts
    need, n, count, i = PEAK_PROMINENCE * sp.max(), len(x), 0, 1
    while i < n - 1:
        if x[i - 1] < x[i]:
            ahead = i + 1
            while ahead < n - 1 and x[ahead] == x[i]:
                ahead += 1
            if x[ahead] < x[i]:
                count += prominence(x, (i + ahead - 1) // 2) >= need
                i = ahead
        i += 1
    return count


def prominence(x: list[float], p: int) -> float:
    """The prominence of the peak at ``x[p]``: its height over the higher of the lowest
    points between it and the nearest higher point (or the end) on either side."""
    h, lows = x[p], []
    for step in (-1, 1):
        i, low = p, h
        while 0 <= i < len(x) and x[i] <= h:
            low = min(low, x[i])
            i += step
        lows.append(low)
    return h - max(lows)


def power_law_exponent(pos: np.ndarray, fs: float, min_curvature: float = 2.0):
    """The fitted beta of speed ~ curvature^beta over the samples of ``pos`` (T, 3) whose
    curvature exceeds ``min_curvature`` [1/m] (a straight path has no exponent: NaN when
    fewer than 5 samples are curved)."""
    dt = 1.0 / fs
    vel = np.gradient(np.asarray(pos, float), dt, axis=0)
    acc = np.gradient(vel, dt, axis=0)
    v = np.linalg.norm(vel, axis=1)
    cross = np.linalg.norm(np.cross(vel, acc), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = cross / v**3
    ok = np.isfinite(kappa) & (kappa > min_curvature) & (v > 1e-3)
    if ok.sum() < 5:
        return float("nan")
    beta, _ = np.polyfit(np.log(kappa[ok]), np.log(v[ok]), 1)
    return float(beta)


@dataclasses.dataclass(frozen=True)
class Movement:
    """One movement of a point between two pauses: frames ``[first, last]``."""

    first: int
    last: int
    duration: float  # [s]
    path_length: float  # [m]
    peak_speed: float  # [m/s]
    mean_speed: float  # [m/s]
    sparc: float
    ldlj: float
    peaks: int
    power_law: float  # NaN on a straight path


def runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """``(first, last)`` frame indices of each run of consecutive True ``flags``."""
    f = np.flatnonzero(flags)
    if not f.size:
        return []
    cut = np.flatnonzero(np.diff(f) > 1)
    return list(zip(f[np.r_[0, cut + 1]].tolist(), f[np.r_[cut, len(f) - 1]].tolist()))


def segments(sp: np.ndarray, fs: float) -> list[tuple[int, int]]:
    """Frame ranges ``(first, last)`` where speed ``sp`` exceeds the moving threshold,
    pauses shorter than :data:`MERGE_GAP` bridged; each range is widened to the frames where
    the speed falls to its local minimum, so a movement starts and ends at rest."""
    sp = np.asarray(sp, float)
    if sp.size == 0 or sp.max() <= 0.0:
        return []
    moving = sp > max(MOVING_SPEED, MOVING_FRACTION * sp.max())
    runs, start = [], None
    for i, m in enumerate(np.r_[moving, False]):
        if m and start is None:
            start = i
        elif not m and start is not None:
            runs.append([start, i - 1])
            start = None
    merged: list[list[int]] = []
    for r in runs:
        if merged and (r[0] - merged[-1][1]) / fs <= MERGE_GAP:
            merged[-1][1] = r[1]
        else:
            merged.append(r)
    out = []
    for a, b in merged:
        while a > 0 and sp[a - 1] < sp[a]:
            a -= 1
        while b < len(sp) - 1 and sp[b + 1] < sp[b]:
            b += 1
        out.append((a, b))
    return out


def movements(pos: np.ndarray, fs: float) -> list[Movement]:
    """The movements of a point sampled as ``pos`` (T, 3) at ``fs`` [Hz], with their measures."""
    pos = np.asarray(pos, float)
    sp = speed(pos, fs)
    out = []
    for a, b in segments(sp, fs):
        seg, s = pos[a : b + 1], sp[a : b + 1]
        if len(seg) < 4:
            continue
        out.append(
            Movement(
                first=a,
                last=b,
                duration=(b - a) / fs,
                path_length=float(np.linalg.norm(np.diff(seg, axis=0), axis=1).sum()),
                peak_speed=float(s.max()),
                mean_speed=float(s.mean()),
                sparc=sparc(s, fs),
                ldlj=ldlj(seg, fs),
                peaks=speed_peaks(s),
                power_law=power_law_exponent(seg, fs),
            )
        )
    return out
