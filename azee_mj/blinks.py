"""Automatic blinks: a score with spontaneous eye blinks added (a pure transform).

People blink about 17 times a minute at rest (Bentivoglio et al. 1997, "Analysis of blink
rate patterns in normal subjects", Movement Disorders 12(6): 15-20 a minute at rest, more in
conversation, fewer when reading), each blink lasting 0.1 to 0.4 s. :func:`add_blinks` draws
blink times from a seeded generator (the same seed gives the same blinks) and adds, for each,
three morph blocks under the root: the lids held open for ``LEAD`` s, closed for ``SHUT`` s
(``eyeBlink`` at weight 1), open again for ``REOPEN`` s. The timeline blends the lids between
them as fast as a blink (about 0.18 s to close, 0.1 s to open, with the bundled rig). No blink
overlaps a block that constrains an eyelid (any morph that moves an eyelid joint, or a hold of
such a block), by ``MARGIN`` s either side. Times in seconds.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from azee_mj import score as sc
from azee_mj.errors import AzeeError
from azee_mj.sites import DEFAULT_MAP, SignerMap

#: Mean spontaneous blink rate [blinks per minute] (Bentivoglio et al. 1997, at rest).
RATE_PER_MIN = 17.0
#: Shortest interval between two blinks [s].
MIN_INTERVAL = 1.0
#: The blink's blocks [s]: lids held open before, shut, open again after.
LEAD, SHUT, REOPEN = 0.3, 0.05, 0.3
#: Clearance from a block that constrains an eyelid [s].
MARGIN = 0.1
#: The morph that closes both eyes.
MORPH = "eyeBlink"


def eyelid_joints(signer_map: SignerMap = DEFAULT_MAP) -> frozenset[str]:
    """The joints :data:`MORPH` moves (both sides): the eyelids."""
    return frozenset(signer_map.morphs[MORPH].joint_changes(None))


def _moves_lids(block: sc.Block, lids: frozenset[str], signer_map: SignerMap) -> bool:
    for c in block.constraints:
        if isinstance(c, sc.MorphC) and lids & set(signer_map.morphs[c.id].joint_changes(c.side)):
            return True
    return False


def eyelid_intervals(
    score: sc.Score, signer_map: SignerMap = DEFAULT_MAP
) -> list[tuple[float, float]]:
    """``(start, end)`` [s] of the blocks that constrain an eyelid: cstr blocks with a morph
    moving one, and holds of a block holding such a block."""
    lids = eyelid_joints(signer_map)
    by_path = {b.path: b for b in score.blocks()}

    def constrains(b: sc.Block) -> bool:
        if b.kind is sc.BlockKind.CSTR:
            return _moves_lids(b, lids, signer_map)
        if b.kind is sc.BlockKind.HOLD and b.hold_of in by_path:
            return any(constrains(x) for x in by_path[b.hold_of].blocks())
        return False

    return sorted((b.start, b.end) for b in score.blocks() if b is not score.root and constrains(b))


def blink_times(
    duration: float,
    seed: int,
    busy: list[tuple[float, float]] = (),
    rate: float = RATE_PER_MIN,
) -> list[float]:
    """The times [s] the lids are shut in a score of ``duration`` s: intervals drawn from a
    gamma distribution (shape 2, mean 60 / ``rate`` s, at least ``MIN_INTERVAL``), each blink
    kept if its blocks fit in the score and clear the ``busy`` intervals by ``MARGIN``."""
    if not rate > 0:
        raise AzeeError(f"--blink-rate: the blink rate must be positive, got {rate}")
    rng = np.random.default_rng(seed)
    mean = 60.0 / rate
    out, t = [], 0.0
    while True:
        t += max(MIN_INTERVAL, float(rng.gamma(2.0, mean / 2.0)))
        lo, hi = t - LEAD, t + SHUT + REOPEN
        if hi > duration:
            return out
        if lo >= 0 and all(hi + MARGIN <= s or lo - MARGIN >= e for s, e in busy):
            out.append(round(t, 3))


def _block(root: sc.Block, name: str, start: float, end: float, weight: float) -> sc.Block:
    morph = sc.MorphC(id=MORPH, weight=weight)
    return sc.Block(
        name=name,
        path=f"{root.path}.{name}",
        kind=sc.BlockKind.CSTR,
        start=start,
        end=end,
        constraints=(morph,),
        annotations={"x-auto": "blink"},
    )


def add_blinks(
    score: sc.Score,
    seed: int,
    rate: float = RATE_PER_MIN,
    signer_map: SignerMap = DEFAULT_MAP,
) -> sc.Score:
    """``score`` with automatic blinks (see the module's docstring): deterministic for a
    ``seed``. The blocks are named ``BLINK<k>_OPEN``, ``BLINK<k>``, ``BLINK<k>_REOPEN``
    (a number ``k`` no sibling name uses)."""
    root = score.root
    if root.kind is not sc.BlockKind.SYNC:
        raise AzeeError(
            f"--blinks: the root block {root.path!r} is a {root.kind.value} block; automatic "
            "blinks need a sync root to add their blocks to"
        )
    times = blink_times(score.duration, seed, eyelid_intervals(score, signer_map), rate)
    taken = {c.name for c in root.children}
    added, k = [], 0
    for t in times:
        while any(f"BLINK{k}{s}" in taken for s in ("", "_OPEN", "_REOPEN")):
            k += 1
        t0 = root.start + t
        added += [
            _block(root, f"BLINK{k}_OPEN", t0 - LEAD, t0, 0.0),
            _block(root, f"BLINK{k}", t0, t0 + SHUT, 1.0),
            _block(root, f"BLINK{k}_REOPEN", t0 + SHUT, t0 + SHUT + REOPEN, 0.0),
        ]
        k += 1
    if not added:
        return score
    new_root = dataclasses.replace(root, children=root.children + tuple(added))
    return dataclasses.replace(score, root=new_root)
