"""Which part of the signer carries what: the one place that answers "which arm carries
this site", "which hand is this body in", "where does this limb hang from".

:class:`SignerAnatomy` reads the model's body tree and the signer map's arm bones
(``arm_X``, ``f_arm_X``, ``palm_X``); the schedule, the analytic seeds and the natural
preferences all ask it.

Units: metres.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco

from azee_mj import reach
from azee_mj.kinematics import BodyOrigin, Const, Expr, Lin
from azee_mj.reach import Arm
from azee_mj.sites import SignerMap

#: Where the palm of an arm that the other hand touches (its elbow, forearm, upper arm)
#: rests, from that arm's shoulder joint [m]: forward, toward the midline, up. Its forearm
#: comes up in front of the body with the elbow bent and low, where the other hand meets it.
ACROSS = (0.25, 0.0, 0.1)


def descends(model: mujoco.MjModel, body: int, ancestor: int) -> bool:
    """Whether ``body`` is ``ancestor`` or one of its descendants."""
    while body > 0:
        if body == ancestor:
            return True
        body = int(model.body_parentid[body])
    return False


class Carrier(NamedTuple):
    """The arm whose forearm or upper arm carries a site (not on its hand), that arm's
    palm site, and where that palm rests while the other hand touches the arm."""

    arm: Arm
    palm: str
    rest: Expr


class SignerAnatomy:
    """Body-tree queries on ``model`` for the signer mapped by ``smap``: the arms, the hand
    or arm carrying a site, the palm of an arm, the bodies that touch as one hand."""

    def __init__(self, model: mujoco.MjModel, smap: SignerMap):
        self.model, self.smap = model, smap
        #: The arms whose bodies the model has, right then left.
        self.arms = tuple(a for a in reach.arms_of(smap) if self._body(a.hand) >= 0)
        #: Hand (``palm_X``) and forearm (``f_arm_X``) bodies, left then right.
        self.hands = self._bones("palm")
        self.forearms = self._bones("f_arm")
        self.palms = {a: self._palm_site(a) for a in self.arms}
        self._carrying: dict[tuple[str, str], Arm | None] = {}

    def _bones(self, stem: str) -> tuple[int, ...]:
        bones = self.smap.bones
        return tuple(self._body(bones[f"{stem}_{x}"].body) for x in "LR" if f"{stem}_{x}" in bones)

    def _body(self, name: str) -> int:
        return mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)

    def site_body(self, site: str) -> int:
        """The body id that model ``site`` is on."""
        return int(
            self.model.site_bodyid[mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, site)]
        )

    def arm_carrying(self, site: str, part: str = "hand") -> Arm | None:
        """The arm whose ``part`` (``hand``, ``fore`` or ``upper``) carries model ``site``,
        or None (looked up once per site)."""
        key = (site, part)
        if key not in self._carrying:
            body = self.site_body(site)
            self._carrying[key] = next(
                (a for a in self.arms if descends(self.model, body, self._body(getattr(a, part)))),
                None,
            )
        return self._carrying[key]

    def hand_of(self, site: str) -> Arm | None:
        """The arm whose hand carries model ``site``, or None."""
        return self.arm_carrying(site)

    def carried_by(self, site: str) -> Carrier | None:
        """The arm whose forearm or upper arm (not its hand) carries model ``site``, with
        its palm site and where that palm rests (:func:`across`); None if no arm does or
        the site is on a hand."""
        arm = self.arm_carrying(site, "upper")
        if arm is None or self.hand_of(site) is arm:
            return None
        palm = self.palms[arm]
        return None if palm is None else Carrier(arm, palm, across(arm))

    def limb_root(self, site: str) -> int | None:
        """The body a site's arm hangs from (its clavicle), or None off the arms."""
        arm = self.arm_carrying(site, "upper")
        return None if arm is None else int(self.model.body_parentid[self._body(arm.upper)])

    def on_forearm(self, site: str) -> bool:
        """Whether model ``site`` rides on a forearm or hand (a part the other arm brings to
        a contact; the shoulder and the upper arm stay where they are)."""
        body = self.site_body(site)
        return any(descends(self.model, body, fore) for fore in self.forearms)

    def part(self, body: int) -> tuple[int, ...]:
        """The bodies that touch as one with ``body``: its whole hand if it is in one."""
        m = self.model
        for hand in self.hands:
            if descends(m, body, hand):
                return tuple(b for b in range(m.nbody) if descends(m, b, hand))
        return (body,)

    def joins_hands(self, site: str, other: str) -> bool:
        """Whether model sites ``site`` and ``other`` are on two different hands."""
        arm, other_arm = self.hand_of(site), self.hand_of(other)
        return arm is not None and other_arm is not None and other_arm is not arm

    def _palm_site(self, arm: Arm) -> str | None:
        """The model site of the palm's centre (AZee ``PA``) on ``arm``'s hand, or None."""
        hand = self._body(arm.hand)
        return next(
            (
                s
                for a, s in self.smap.sites.items()
                if a.startswith("PA_") and self.site_body(s) == hand
            ),
            None,
        )


def across(arm: Arm) -> Expr:
    """Where the palm of ``arm`` rests when the other hand touches that arm: ``ACROSS``
    from its shoulder joint (forward, toward the midline, up) [m]."""
    fwd, inward, up = ACROSS
    return Lin(((1.0, BodyOrigin(arm.upper)), (1.0, Const((fwd, arm.out * -inward, up)))))
