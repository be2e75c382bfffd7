"""A report of how a score was realized: its timeline per track, the IK work and the
residuals, as one self-contained HTML page (PNG figures embedded in base64) or a PNG set.

Needs matplotlib (``pip install azee_mj[plot]``); uses its ``Agg`` backend, no display.
"""

from __future__ import annotations

import base64
import dataclasses
import html
import io
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import score as sc
from azee_mj.errors import AzeeError, printable
from azee_mj.timeline import Rollout

PLOT_HINT = "pip install azee_mj[plot]"
#: How many of the hardest IK problems get a convergence curve.
HARDEST = 6

_KIND_COLOR = {"cstr": "#4c72b0", "hold": "#8c8c8c", "transpath": "#dd8452"}


class Recorder:
    """An observer of a solver (its ``on_solve``): keeps every problem solved and its
    result, in order (``records``)."""

    def __init__(self):
        self.records: list[tuple[ik.IKProblem, ik.IKResult]] = []

    def __call__(self, problem: ik.IKProblem, result: ik.IKResult) -> None:
        self.records.append((problem, result))


@dataclasses.dataclass(frozen=True)
class Realization:
    """A rollout with the IK problems solved for it (in solving order)."""

    score: sc.Score
    rollout: Rollout
    records: tuple[tuple[ik.IKProblem, ik.IKResult], ...]


def realize_recorded(
    score, fps: float = 50.0, progress=None, dynamics: bool = False
) -> Realization:
    """Realize ``score`` keeping every IK problem and result (with its cost history);
    ``dynamics``: then simulate it (:func:`azee_mj.physics.simulate`)."""
    from azee_mj.schedule import make_solver
    from azee_mj.timeline import realize

    s = score if isinstance(score, sc.Score) else sc.load_score(score)
    recorder = Recorder()
    solver = make_solver(on_solve=recorder)
    rollout = realize(s, fps=fps, solver=solver, progress=progress)
    if dynamics:
        from azee_mj.physics import simulate

        rollout = simulate(rollout, s, solver=solver)
    return Realization(s, rollout, tuple(recorder.records))


def _dynamics_table(ro) -> str:
    """Per block of a physics rollout: tracking error, peak torque against its limit and
    energy (empty for a kinematic rollout)."""
    if not hasattr(ro, "torque_limit"):
        return ""
    rows = "\n".join(
        f"<tr><td>{html.escape(b.block)}</td><td>{b.tracking_site * 1000:.2f}</td>"
        f"<td>{np.degrees(b.tracking_joint):.2f}</td><td>{100 * b.peak_ratio:.0f}% "
        f"({html.escape(b.peak_joint)})</td><td>{b.energy:.2f}</td><td>{b.tie_force:.1f}</td></tr>"
        for b in ro.blocks()
    )
    return (
        f"<h2>Dynamics</h2>\n<p>{html.escape(ro.summary())}</p>\n<table><tr><th>block</th>"
        "<th>tracking, sites [mm]</th><th>tracking, joints [deg]</th>"
        "<th>peak torque / limit</th><th>energy [J]</th><th>equality pull [N]</th></tr>\n"
        + rows
        + "\n</table>"
    )


def _plt():
    try:
        import matplotlib
    except ImportError:
        raise AzeeError(f"the report needs matplotlib: {PLOT_HINT}") from None
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _below(path: str, root: str) -> str:
    """A block's path below the root."""
    return path[len(root) + 1 :] if path.startswith(root + ".") else path


def _short(path: str, root: str) -> str:
    """A block's path below the root, as plain text for a figure (:func:`_plain`)."""
    return _plain(_below(path, root))


def _plain(text: str) -> str:
    """``text`` for a matplotlib label: every ``$`` escaped, so a name is never parsed as
    mathtext (``$\\frac{$`` would raise); control characters written as escapes."""
    return printable(text).replace("$", r"\$")


# ---------------------------------------------------------------------------------------
# Figures
# ---------------------------------------------------------------------------------------


def fig_timeline(r: Realization):
    """Rows = articulator tracks, bars = the blocks driving them, named (a score figure)."""
    plt = _plt()
    sched = r.rollout.schedule
    tracks = list(sched)
    root = r.score.root.path
    kinds = {b.path: b.kind.value for b in r.score.blocks()}
    fig, ax = plt.subplots(figsize=(10, 0.45 * len(tracks) + 1.4))
    for row, t in enumerate(tracks):
        y = len(tracks) - 1 - row
        for iv in sched[t]:
            color = _KIND_COLOR.get(kinds.get(iv.block, ""), "#55a868")
            ax.barh(
                y,
                iv.end - iv.start,
                left=iv.start,
                height=0.7,
                color=color,
                edgecolor="black",
                linewidth=0.6,
            )
            ax.text(
                0.5 * (iv.start + iv.end),
                y,
                _short(iv.block, root),
                ha="center",
                va="center",
                fontsize=8,
                color="white",
                clip_on=True,
            )
    ax.set_yticks(range(len(tracks)), list(reversed(tracks)))
    ro = r.rollout
    end = float(ro.time[-1]) if len(ro.time) else r.score.duration
    ax.set_xlim(0, max(end, ro.score_start + r.score.duration))
    # the lead-in from rest and the return to rest: the realizer's time, not the score's
    for a, b in ((0.0, ro.score_start), (ro.score_start + r.score.duration, end)):
        if b > a:
            ax.axvspan(a, b, color="0.9", zorder=0)
    ax.set_xlabel("time [s]")
    ax.set_title(f"{_plain(root)}: blocks per articulator track")
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in _KIND_COLOR.values()]
    ax.legend(handles, list(_KIND_COLOR), loc="upper right", fontsize=8, ncols=3)
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    return fig


def fig_problems(r: Realization):
    """Per IK problem: hard constraints and LM iterations (key postures, then frames)."""
    plt = _plt()
    n_key = r.rollout.stats.key_problems
    counts = [sum(not getattr(c, "soft", False) for c in p.constraints) for p, _ in r.records]
    iters = [res.iterations for _, res in r.records]
    ok = [res.converged for _, res in r.records]
    x = np.arange(len(r.records))
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 5), sharex=True)
    col = ["#4c72b0" if i < n_key else "#8cb0d8" for i in x]
    a1.bar(x, counts, color=col)
    a1.set_ylabel("hard constraints")
    a1.set_title(f"{len(x)} IK problems: {n_key} key postures (dark), then constrained frames")
    a2.bar(x, iters, color=[c if k else "#c44e52" for c, k in zip(col, ok)])
    a2.set_ylabel("LM iterations")
    a2.set_xlabel("IK problem (solving order); red = not converged")
    for a in (a1, a2):
        a.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return fig


def fig_convergence(r: Realization, k: int = HARDEST):
    """Cost per LM iteration of the ``k`` problems that took the most iterations."""
    plt = _plt()
    order = sorted(range(len(r.records)), key=lambda i: -r.records[i][1].iterations)[:k]
    fig, ax = plt.subplots(figsize=(10, 4))
    for i in order:
        p, res = r.records[i]
        labels = sorted(
            {
                c.label.split("#")[0]
                for c in p.constraints
                if isinstance(c, (cn.Place, cn.Orient, cn.Look))
            }
        )
        name = ", ".join(_short(lb, r.score.root.path) for lb in labels) or "joint targets"
        h = np.maximum(res.history, 1e-12)
        ax.semilogy(
            np.arange(1, len(h) + 1), h, marker=".", label=f"#{i} {name} ({res.iterations} it.)"
        )
    ax.set_xlabel("LM iteration")
    ax.set_ylabel("cost (sum of squared rows / tol)")
    ax.set_title(f"Convergence of the {len(order)} hardest IK problems")
    ax.grid(alpha=0.3, which="both")
    if order:
        ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def fig_residuals(r: Realization):
    """Each constraint's residual over its block's interval, with its tolerance."""
    plt = _plt()
    t = r.rollout.time
    root = r.score.root.path
    fig, axes = plt.subplots(2, 1, figsize=(10, 5.5), sharex=True)
    for ax, unit, scale, name in (
        (axes[0], "m", 1000.0, "mm"),
        (axes[1], "rad", 180 / np.pi, "deg"),
    ):
        n = 0
        for tr in r.rollout.traces:
            if tr.unit != unit:
                continue
            (line,) = ax.plot(
                t, tr.values * scale, label=f"{_short(tr.block, root)}#{tr.index} ({tr.kind})"
            )
            ax.hlines(
                tr.tol * scale,
                tr.start,
                tr.end,
                colors=line.get_color(),
                linestyles="dashed",
                linewidth=0.8,
            )
            n += 1
        ax.set_ylabel(f"residual [{name}]")
        ax.grid(alpha=0.3)
        if n:
            ax.legend(fontsize=8, loc="upper right")
        else:
            ax.text(0.5, 0.5, f"no constraint in {name}", transform=ax.transAxes, ha="center")
    axes[0].set_title("Residual per constraint over time (dashed: tolerance)")
    axes[1].set_xlabel("time [s]")
    fig.tight_layout()
    return fig


FIGURES = (
    ("timeline", "Timeline", fig_timeline),
    ("ik_problems", "IK problems", fig_problems),
    ("convergence", "Convergence", fig_convergence),
    ("residuals", "Residuals", fig_residuals),
)


def _png(fig) -> bytes:
    plt = _plt()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return buf.getvalue()


# ---------------------------------------------------------------------------------------
# Output
# ---------------------------------------------------------------------------------------


def _html(r: Realization, images: dict[str, bytes]) -> str:
    ro, s = r.rollout, r.rollout.stats
    root = r.score.root.path
    worst: dict[str, list[str]] = {}
    for tr in ro.traces:
        scale, unit = (1000.0, "mm") if tr.unit == "m" else (180 / np.pi, "deg")
        worst.setdefault(tr.block, []).append(
            f"#{tr.index} {tr.kind} {tr.worst * scale:.2f} {unit}"
            + ("" if tr.ok else f" (over {tr.tol * scale:.2f})")
            + (f": {tr.reason}" if tr.reason and not tr.ok else "")
        )
    rows = []
    for b in r.score.blocks():
        detail = ""
        if b.kind is sc.BlockKind.CSTR:
            detail = ", ".join(c.TYPE for c in b.constraints)
        elif b.kind is sc.BlockKind.HOLD:
            detail = f"holds {_below(b.hold_of or '', root)}"
        elif b.kind is sc.BlockKind.TRANSPATH:
            detail = f"{b.transpath_site} {type(b.route).__name__.lower()}"
        rows.append(
            "<tr>"
            + "".join(
                f"<td>{html.escape(str(v))}</td>"
                for v in (
                    b.path,
                    b.kind.value,
                    f"{b.start:.3f}",
                    f"{b.end:.3f}",
                    detail,
                    "; ".join(worst.get(b.path, [])),
                )
            )
            + "</tr>"
        )
    n_ok = sum(t.ok for t in ro.traces)
    found = "".join(f"<li>{html.escape(f.describe())}</li>" for f in ro.findings)
    found = f"<h2>Findings</h2>\n<ul>{found}</ul>" if found else "<p>No findings.</p>"
    figs = "\n".join(
        f'<h2>{title}</h2>\n<img alt="{key}" src="data:image/png;base64,'
        f'{base64.b64encode(images[key]).decode()}">'
        for key, title, _ in FIGURES
    )
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>azee-mj report: {html.escape(root)}</title>
<style>body{{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}}
table{{border-collapse:collapse;font-size:90%}}td,th{{border:1px solid #ccc;padding:2px 6px}}
th{{background:#eee}}img{{max-width:100%}}</style></head><body>
<h1>Realization of {html.escape(root)}</h1>
<p>{len(ro.time)} frames at {ro.fps:g} fps ({ro.time[-1]:.3f} s), mode {ro.mode.value};
{s.problems} IK problems ({s.key_problems} key postures), {s.iterations} iterations,
{s.not_converged} not converged; solve {s.solve_time * 1000:.1f} ms, total
{s.total_time * 1000:.1f} ms; {n_ok}/{len(ro.traces)} constraints within tolerance.
The score starts at {ro.score_start:.3f} s of the rollout (before it: the lead-in from
rest); block times below are the score's.</p>
{found}
<h2>Blocks</h2>
<table><tr><th>block</th><th>kind</th><th>start [s]</th><th>end [s]</th><th>content</th>
<th>worst residual</th></tr>
{chr(10).join(rows)}
</table>
{_dynamics_table(ro)}
{figs}
</body></html>
"""


def write_report(
    score: str | os.PathLike | sc.Score,
    out: str | os.PathLike,
    *,
    fps: float = 50.0,
    progress: Callable[[float], None] | None = None,
    dynamics: bool = False,
) -> list[Path]:
    """Realize ``score`` and write the report to ``out``: an ``.html`` page with the figures
    embedded, or, when ``out`` ends with ``/`` or is a directory, ``timeline.png``,
    ``ik_problems.png``, ``convergence.png`` and ``residuals.png`` in it. ``dynamics``: in
    the physics mode, the page adds a table of the dynamics per block. Atomic writes;
    returns the paths written."""
    from azee_mj.files import atomic_path
    from azee_mj.timing import check_fps

    out_s = str(out)
    as_dir = out_s.endswith(("/", os.sep)) or Path(out).is_dir()
    if not as_dir and Path(out).suffix.lower() not in (".html", ".htm"):
        raise AzeeError(
            f"-o: expected REPORT.html or a directory DIR/ for PNG files, got {out_s!r}"
        )
    fps = check_fps(fps)
    _plt()
    tick = progress or (lambda f: None)
    r = realize_recorded(score, fps=fps, progress=lambda f: tick(0.5 * f), dynamics=dynamics)
    images = {}
    for k, (key, _, fn) in enumerate(FIGURES):
        images[key] = _png(fn(r))
        tick(0.5 + 0.5 * (k + 1) / len(FIGURES))
    written = []
    if as_dir:
        d = Path(out)
        for key, data in images.items():
            with atomic_path(d / f"{key}.png") as tmp:
                tmp.write_bytes(data)
            written.append(d / f"{key}.png")
    else:
        with atomic_path(out) as tmp:
            tmp.write_text(_html(r, images), encoding="utf-8")
        written.append(Path(out))
    return written
