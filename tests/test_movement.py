"""The movement measures against their published values on synthetic profiles."""

import numpy as np
import pytest

from azee_mj import movement as mv
from azee_mj.blend import minjerk

FS = 200.0


def reach(distance: float, duration: float) -> np.ndarray:
    t = np.linspace(0.0, duration, round(duration * FS) + 1)
    x = distance * minjerk(t / duration)
    return np.c_[x, np.zeros_like(x), np.zeros_like(x)]


@pytest.mark.parametrize(("distance", "duration"), [(0.5, 0.4), (0.1, 1.0), (0.3, 0.6)])
def test_minimum_jerk_reach_has_the_published_measures(distance, duration):
    pos = reach(distance, duration)
    sp = mv.speed(pos, FS)
    assert sp.max() == pytest.approx(mv.MINJERK_PEAK * distance / duration, rel=1e-3)
    assert mv.sparc(sp, FS) == pytest.approx(-1.40, abs=0.01)
    # -5.32 analytically; central differences on 81 to 201 samples read 0.04 to 0.10 high
    assert mv.ldlj(pos, FS) == pytest.approx(-5.32, abs=0.12)
    assert mv.speed_peaks(sp) == 1


def test_a_stop_halfway_is_two_peaks_and_less_smooth():
    half = reach(0.25, 0.5)
    pos = np.r_[half, half[1:] + [0.25, 0.0, 0.0]]
    sp = mv.speed(pos, FS)
    assert mv.speed_peaks(sp) == 2
    assert mv.sparc(sp, FS) == pytest.approx(-2.25, abs=0.02)


def test_constant_speed_with_ramps():
    t = np.linspace(0.0, 1.0, 201)
    sp = np.clip(np.minimum(t / 0.1, (1.0 - t) / 0.1), 0.0, 1.0)
    assert mv.sparc(sp, FS) == pytest.approx(-2.10, abs=0.02)


def test_ellipse_traced_at_constant_parameter_rate_follows_the_two_thirds_law():
    th = np.linspace(0.0, 2.0 * np.pi, 400)
    pos = np.c_[0.2 * np.cos(th), 0.1 * np.sin(th), np.zeros_like(th)]
    assert mv.power_law_exponent(pos, 100.0) == pytest.approx(-1.0 / 3.0, abs=0.01)


def test_straight_path_has_no_power_law_exponent():
    assert np.isnan(mv.power_law_exponent(reach(0.3, 0.5), FS))


def test_movements_split_at_pauses_and_bridge_short_ones():
    still = np.zeros((40, 3))
    a = reach(0.3, 0.5)
    b = reach(0.2, 0.4) + a[-1]
    pos = np.r_[still, a, still + a[-1], b, still + b[-1]]
    moves = mv.movements(pos, FS)
    assert len(moves) == 2
    assert moves[0].path_length == pytest.approx(0.3, rel=1e-3)
    assert moves[1].path_length == pytest.approx(0.2, rel=1e-3)
    assert all(m.peaks == 1 for m in moves)
    # a 50 ms pause is bridged: one movement with two peaks
    short = np.r_[a, np.repeat(a[-1:], 10, axis=0), b]
    (joined,) = mv.movements(short, FS)
    assert joined.peaks == 2


def test_no_movement_in_a_still_trajectory():
    assert mv.movements(np.zeros((50, 3)), FS) == []


def test_speed_peaks_counts_what_scipy_find_peaks_counts():
    from scipy.signal import find_peaks

    rng = np.random.default_rng(7)
    for n in [3, 4, 5, 8, 20, 60, 200] * 40:
        # rounded to few levels: flat tops, ties between peaks and zero runs happen often
        sp = np.round(rng.random(n) * rng.choice([2, 5, 50]), 0) * rng.random()
        if rng.random() < 0.3:
            sp = np.convolve(sp, np.ones(5) / 5, mode="same")  # smooth bells
        expected = (
            len(find_peaks(np.r_[0.0, sp, 0.0], prominence=mv.PEAK_PROMINENCE * sp.max())[0])
            if sp.max() > 0.0
            else 0
        )
        assert mv.speed_peaks(sp) == expected, sp.tolist()


def test_prominence_of_a_peak_between_two_higher_ones():
    x = [0.0, 3.0, 1.0, 2.0, 0.5, 4.0, 0.0]
    assert mv.prominence(x, 3) == 1.0  # 2 over the higher of its two saddles (1 and 0.5)
    assert mv.prominence(x, 5) == 4.0  # the highest: down to the ends
