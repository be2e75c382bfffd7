"""The posture solver's records: what must hold at one instant, what the solver found, and
why a run stopped.

Units: metres, radians, seconds.
"""

from __future__ import annotations

import dataclasses
import enum

import numpy as np

from azee_mj.constraints import Constraint


class Stop(enum.IntEnum):
    """Why a Levenberg-Marquardt run or a polish stopped (the compiled core's ``Stop``, in
    its order; :attr:`message` says it in words)."""

    DONE = 0
    MET_SLOW = 1
    STALL = 2
    GUIDE_STALL = 3
    DAMPING = 4
    NO_STEP = 5
    MAX_ITER = 6
    NO_FREEDOM = 7
    POLISHED = 8

    @property
    def message(self) -> str:
        return _MESSAGES[self]


_MESSAGES = {
    Stop.DONE: "every constraint within its stop fraction and no contact too deep",
    Stop.MET_SLOW: "every constraint within its tolerance, and the last step gained little",
    Stop.STALL: "three steps of little gain (a local minimum)",
    Stop.GUIDE_STALL: "a step of little gain with the guide toward the preferred posture on",
    Stop.DAMPING: "the damping grew past its bound: no step lowers the cost",
    Stop.NO_STEP: "the step vanished",
    Stop.MAX_ITER: "the iteration budget ran out",
    Stop.NO_FREEDOM: "no direction left that keeps the constraints",
    Stop.POLISHED: "two steps in a row gained nothing worth it",
}


@dataclasses.dataclass(frozen=True)
class IKProblem:
    """What must hold at one instant.

    Attributes:
      constraints: the constraints, all solved together.
      free_joints: model joints the solver may move; None = every joint that moves a
        constrained body (its ancestors). Other joints keep their warm-start value.
      touching: body pairs that may touch (up to ``CONTACT_ALLOWANCE`` deep) besides those
        that a site-to-site placement of this problem brings together.
      prefer: the posture the guide pulls toward while reaching the constraints (the
        realizer passes the current one, for the least motion); None = ``natural``.
      seeds: postures (nq,) to start from besides the warm start (e.g. analytic arm
        postures); every start is tried and the best result by one cost kept.
      max_change: largest change of any free joint from the warm start [rad or m]: a
        per-frame solve stays on the branch of the frame before (restarts stay inside).
      natural: take the most natural posture among the solutions (False: the first one
        reached, e.g. for an intermediate solve).
      collide: keep the body out of itself (False: a transparent body, for diagnosis).
      preferences: constraints that join the naturalness objective (rows scaled by their
        tolerance), e.g. where two hands meet when nothing else says where.
      restarts: further generic attempts when none meets everything (None: the solver's
        own); from 2 up, the solver's ``seeder`` adds its starts to them.
      bounds: (lower, upper), each (nq,): further bounds of the joints inside their ranges
        [rad or m] (e.g. within reach of a later posture), None = none.
      wide: start from the limbs anywhere in their ranges instead of the usual starts (a
        last resort, asked after those missed: a hand behind the head lies where no arm
        seed begins); a meet from there is kept only if it keeps the preferences.
      ranges: the tolerance of each ranged orientation
        (:attr:`~azee_mj.constraints.Orient.ranged`) is a range: its rows are zero within
        ``RANGE_FREE`` of it (:mod:`azee_mj.posture.contract`); else every orientation's
        rows pull its axis toward the middle of its tolerance.
    """

    constraints: tuple[Constraint, ...]
    free_joints: tuple[str, ...] | None = None
    #: Body-name pairs allowed to touch (a contact elsewhere in the score holds them).
    touching: tuple[tuple[str, str], ...] = ()
    #: (nq,) the posture to prefer among the solutions; None = the solver's natural one.
    prefer: np.ndarray | None = dataclasses.field(default=None, compare=False)
    seeds: tuple[np.ndarray, ...] = dataclasses.field(default=(), compare=False)
    max_change: float | None = None
    natural: bool = True
    collide: bool = True
    preferences: tuple[Constraint, ...] = ()
    restarts: int | None = None
    bounds: tuple[np.ndarray, np.ndarray] | None = dataclasses.field(default=None, compare=False)
    wide: bool = False
    ranges: bool = False


@dataclasses.dataclass(frozen=True)
class Residual:
    """One constraint's error on the solution, in its unit ([m] or [rad])."""

    label: str
    kind: str
    value: float
    tol: float
    unit: str

    @property
    def ok(self) -> bool:
        return self.value <= self.tol


@dataclasses.dataclass(frozen=True)
class IKResult:
    """A solved posture and how it was reached.

    Attributes:
      qpos: (nq,) the posture.
      converged: every constraint within its tolerance and no penetration over the limit.
      residuals: per constraint, in problem order.
      penetration: deepest penetration between non-neighbouring geoms [m] (>= 0).
      iterations: accepted + rejected LM iterations, over all restarts.
      restarts: how many restarts were needed.
      time: wall time [s].
      history: (iterations,) the cost (sum of squared normalised rows) after each iteration.
      stop, polish: why the kept attempt's last LM run and its polish stopped.
    """

    qpos: np.ndarray
    converged: bool
    residuals: tuple[Residual, ...]
    penetration: float
    iterations: int
    restarts: int
    time: float
    history: np.ndarray
    #: why the Levenberg-Marquardt run of the kept attempt stopped (None: no run)
    stop: Stop | None = None
    #: why the polish toward the most natural posture stopped (None: not polished)
    polish: Stop | None = None

    @property
    def stop_message(self) -> str:
        """Why the solve ended, in words (the LM run's reason, then the polish's)."""
        if self.stop is None:
            return "not solved"
        if self.polish is None:
            return self.stop.message
        return f"{self.stop.message}; polish: {self.polish.message}"


@dataclasses.dataclass(frozen=True)
class LMRun:
    """One Levenberg-Marquardt run: its posture, cost, whether every row is within its
    tolerance fraction, and its iterations."""

    q: np.ndarray
    cost: float
    done: bool
    iterations: int
    #: every constraint within its tolerance, nothing deeper than allowed (not ``done``
    #: when it stalled short of the tolerance fraction)
    met: bool = False
    #: why it stopped
    stop: Stop = Stop.MAX_ITER


@dataclasses.dataclass(frozen=True)
class Attempt:
    """One attempt's posture, ``rank`` ((0, natural cost) when it meets every constraint
    without penetration, else (1, constraint cost): lower is better), and iterations."""

    q: np.ndarray
    rank: tuple[int, float]
    iterations: int
    stop: Stop | None = None
    polish: Stop | None = None
