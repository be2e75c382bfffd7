"""Tests of azee_mj.score: loading, resolution, absolute times, expressions, bad input."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from azee_mj.errors import AzeeError, ScoreError
from azee_mj.kinematics import Kinematics, compile_point, compile_vector
from azee_mj.model import load_model
from azee_mj.score import (
    Arc,
    Axis,
    Block,
    BlockKind,
    BoneRef,
    Circle,
    Look,
    MorphC,
    Orient,
    Place,
    PLiteral,
    PMid,
    PSite,
    PTranslate,
    Rel,
    SiteRef,
    Straight,
    Trill,
    VAdd,
    VAxis,
    VBoneAxis,
    VCross,
    VFrom,
    VLiteral,
    VOpp,
    VScale,
    VUnit,
    depends_on_body,
    load_score,
    referenced_bones,
    referenced_sites,
)
from azee_mj.score.grammar import VECTOR_DESC, ExpressionReader
from azee_mj.score.references import References
from azee_mj.score.validation import Loc, check_holds
from azee_mj.sites import DEFAULT_MAP
from azee_mj.timing import child_span, exact_time, root_span

DATA = Path(__file__).parent / "data"


# ---------------------------------------------------------------------------------------
# Builders of small scores
# ---------------------------------------------------------------------------------------


def top(**kw):
    d = {
        "format": "azee-score",
        "version": 1,
        "strong_side": "R",
        "root": {"name": "ROOT", "kind": "sync", "start": 0, "end": 2, "children": []},
    }
    d.update(kw)
    return d


def kids(*children, strong_side="R"):
    root = {"name": "ROOT", "kind": "sync", "start": 0, "end": 2, "children": list(children)}
    return top(root=root, strong_side=strong_side)


def cstr(name="K1", start=0, end=1, constraints=(), **kw):
    return {
        "name": name,
        "kind": "cstr",
        "start": start,
        "end": end,
        "constraints": list(constraints),
        **kw,
    }


def cs(*constraints, strong_side="R"):
    return kids(cstr(constraints=constraints), strong_side=strong_side)


def place(site="@I_TIP(s)", at="@CH", **kw):
    return {"type": "place", "site": site, "at": at, **kw}


def orient(vector="up", bone="!f_arm(s)", axis="dir", rel="along", **kw):
    return {"type": "orient", "bone": bone, "axis": axis, "rel": rel, "vector": vector, **kw}


def tp(path, site="@I_TIP(s)"):
    return kids(
        {"name": "T", "kind": "transpath", "start": 0, "end": 1, "site": site, "path": path}
    )


def drop(d, key):
    d = copy.deepcopy(d)
    del d[key]
    return d


def only_constraint(score):
    (c,) = score.block("ROOT.K1").constraints
    return c


# ---------------------------------------------------------------------------------------
# The example of the format document
# ---------------------------------------------------------------------------------------


def test_example_loads_with_resolved_records_and_absolute_times():
    score = load_score(DATA / "good.json")
    assert score.strong_side == "R"
    assert [b.path for b in score.blocks()] == ["GOOD", "GOOD.PERM", "GOOD.K1", "GOOD.T", "GOOD.K2"]
    root = score.root
    assert (root.kind, root.start, root.end) == (BlockKind.SYNC, 0.0, 1.2)
    perm, k1, t, k2 = root.children
    assert perm.constraints == (
        MorphC(id="fist", weight=1.0, side="R", index=1),
        MorphC(id="thumb_extended", weight=1.0, side="R", index=2),
    )
    assert (k1.start, k1.end) == (0.0, 0.4)
    up, fwd = VAxis((0.0, 0.0, 1.0), "up"), VAxis((1.0, 0.0, 0.0), "fwd")
    assert k1.constraints == (
        Place(
            SiteRef("T_TIP_R"),
            PTranslate(PSite(SiteRef("CH")), VScale(fwd, 0.06)),
            tol=0.001,
            index=1,
        ),
        Orient(
            BoneRef("f_arm_R"),
            Axis.DIR,
            Rel.ALONG,
            VAdd((up, VAxis((0.0, 1.0, 0.0), "left"))),
            tol=math.radians(1),
            index=2,
        ),
    )
    assert t.kind is BlockKind.TRANSPATH
    assert (t.start, t.end) == (0.4, 0.8)
    assert t.transpath_site == SiteRef("T_TIP_R")
    assert t.route == Arc(VScale(up, 0.04))
    assert (k2.kind, k2.start, k2.end) == (BlockKind.CSTR, 0.8, 1.2)
    assert k2.constraints[0].at == PTranslate(PSite(SiteRef("ssp", locus=True)), VScale(up, 0.05))
    assert score.block("GOOD.K2") is k2
    # immutable records
    with pytest.raises(AttributeError):
        k2.start = 0.0  # type: ignore[misc]
    assert isinstance(root.children, tuple) and isinstance(k1.constraints, tuple)


def test_loading_a_dict_equals_loading_the_file():
    data = json.loads((DATA / "good.json").read_text())
    assert load_score(data) == load_score(str(DATA / "good.json"))


def test_nested_sync_offsets_its_children_and_root_start_is_time_zero():
    inner = {
        "name": "S",
        "kind": "sync",
        "start": 0.5,
        "end": 1.5,
        "children": [
            cstr(start=0.25, end=0.75),
            {
                "name": "S2",
                "kind": "sync",
                "start": 0.5,
                "end": 1.0,
                "children": [cstr(name="DEEP", start=0.1, end=0.2)],
            },
        ],
    }
    data = top(root={"name": "ROOT", "kind": "sync", "start": 3, "end": 5, "children": [inner]})
    score = load_score(data)
    assert (score.root.start, score.root.end) == (0.0, 2.0)
    assert score.duration == 2.0
    k1 = score.block("ROOT.S.K1")
    assert (k1.start, k1.end) == (0.75, 1.25)
    deep = score.block("ROOT.S.S2.DEEP")
    assert deep.start == pytest.approx(1.1) and deep.end == pytest.approx(1.2)


def test_hold_transpath_shapes_and_annotations():
    data = kids(
        cstr(**{"x-note": {"a": [1, 2]}}, constraints=[place(**{"x-why": "contact"})]),
        {"name": "H", "kind": "hold", "start": 1, "end": 1.5, "of": "K1"},
        {
            "name": "T",
            "kind": "transpath",
            "start": 1.5,
            "end": 2,
            "site": "@PA(w)",
            "path": {"shape": "circle", "center": "@CH", "turns": 2, "normal": "fwd", "x-todo": 1},
        },
    )
    data["x-source"] = ":arbre"
    score = load_score(data)
    assert score.annotations == {"x-source": ":arbre"}
    k1 = score.block("ROOT.K1")
    assert k1.annotations["x-note"]["a"] == (1, 2)
    assert k1.constraints[0].annotations == {"x-why": "contact"}
    hold = score.block("ROOT.H")
    assert (hold.kind, hold.hold_of, hold.children, hold.constraints) == (
        BlockKind.HOLD,
        "ROOT.K1",
        (),
        (),
    )
    t = score.block("ROOT.T")
    assert t.transpath_site == SiteRef("PA_L")
    assert t.route == Circle(PSite(SiteRef("CH")), 2.0, VAxis((1.0, 0.0, 0.0), "fwd"))
    straight = load_score(tp({"shape": "straight"})).block("ROOT.T").route
    assert straight == Straight()
    circle = load_score(tp({"shape": "circle", "center": [0.3, 0, 0.4]})).block("ROOT.T").route
    assert circle == Circle(PLiteral((0.3, 0.0, 0.4)), 1.0, None)


def test_constraint_types_and_units():
    score = load_score(
        cs(
            place(tol=0.005),
            orient(rel="perp", axis="nrm", tol_deg=5),
            {"type": "morph", "id": "jaw_open", "weight": -0.5},
            {"type": "morph", "id": "blink", "weight": 1},
            {"type": "look", "at": "^Rssp"},
            {
                "type": "trill",
                "site": "@I_TIP(w)",
                "vector": "up",
                "amplitude": 0.01,
                "frequency": 4,
            },
            {
                "type": "trill",
                "bone": "!palm(s)",
                "vector": {"dir": "!f_arm(s)"},
                "amplitude_deg": 10,
                "frequency": 3,
            },
        )
    )
    p, o, m1, m2, look, ts, tb = score.block("ROOT.K1").constraints
    assert p.tol == 0.005 and p.index == 1
    assert (o.axis, o.rel, o.index) == (Axis.NRM, Rel.PERP, 2)
    assert o.tol == pytest.approx(math.radians(5))
    assert m1 == MorphC("jaw_open", -0.5, None, index=3)
    assert m2 == MorphC("blink", 1.0, None, index=4)
    assert look == Look(PSite(SiteRef("Rssp", locus=True)), index=5)
    assert ts == Trill(SiteRef("I_TIP_L"), None, VAxis((0.0, 0.0, 1.0), "up"), 0.01, 4.0, index=6)
    assert tb.site is None and tb.bone == BoneRef("palm_R")
    assert tb.vector == VBoneAxis(BoneRef("f_arm_R"), Axis.DIR)
    assert tb.amplitude == pytest.approx(math.radians(10)) and tb.frequency == 3.0


# ---------------------------------------------------------------------------------------
# References and sides
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("written", "strong", "expected"),
    [
        ("@FH", "R", SiteRef("FH")),
        ("@I_TIP(s)", "R", SiteRef("I_TIP_R")),
        ("@I_TIP(s)", "L", SiteRef("I_TIP_L")),
        ("@EL(w)", "R", SiteRef("EL_L")),
        ("@EL(w)", "L", SiteRef("EL_R")),
        ("@PA(R)", "L", SiteRef("PA_R")),
        ("@PA(L)", "R", SiteRef("PA_L")),
        ("@I_KN(s,2)", "R", SiteRef("I_KN_R_2")),
        ("@I_KN(w, 3)", "R", SiteRef("I_KN_L_3")),
        ("@MO", "R", SiteRef("MO")),
        ("@MO(s)", "R", SiteRef("MO_R")),
        ("@I_TIP_R", "L", SiteRef("I_TIP_R")),
        ("^ssp", "R", SiteRef("ssp", locus=True)),
        ("^Rssp", "L", SiteRef("Rssp", locus=True)),
        ("^Lssp", "R", SiteRef("Lssp", locus=True)),
    ],
)
def test_site_references(written, strong, expected):
    c = only_constraint(load_score(cs(place(site="@CH", at=written), strong_side=strong)))
    assert c.at == PSite(expected)
    assert expected.model_site(DEFAULT_MAP) == expected.name  # identity on the bundled model


@pytest.mark.parametrize(
    ("written", "strong", "expected"),
    [
        ("!f_arm(s)", "R", "f_arm_R"),
        ("!f_arm(s)", "L", "f_arm_L"),
        ("!palm(w)", "R", "palm_L"),
        ("!head", "R", "head"),
        ("!back_2", "R", "back_2"),
        ("!index(s,2)", "R", "index_R_2"),
        ("!index(s,2)", "L", "index_L_2"),
        ("!thumb(w,1)", "R", "thumb_L_1"),
        ("!eye(s)", "R", "eye_R"),
        ("!clav(R)", "L", "clav_R"),
    ],
)
def test_bone_references(written, strong, expected):
    c = only_constraint(load_score(cs(orient(bone=written), strong_side=strong)))
    assert c.bone == BoneRef(expected)
    assert c.bone.model_body(DEFAULT_MAP) == DEFAULT_MAP.bones[expected].body


def test_strong_side_left_mirrors_relative_sides():
    data = cs(
        place(site="@I_TIP(s)", at={"translate": "@CH", "by": "lat(s)"}),
        orient(bone="!palm(w)", vector="lat(w)"),
        {"type": "morph", "id": "fist", "weight": 1, "side": "s"},
        strong_side="L",
    )
    score = load_score(data)
    assert score.strong_side == "L"
    p, o, m = score.block("ROOT.K1").constraints
    assert p.site == SiteRef("I_TIP_L")
    assert p.at.v == VAxis((0.0, 1.0, 0.0), "left")  # lat(s) -> +y with a left strong side
    assert o.bone == BoneRef("palm_R")
    assert o.vector == VAxis((0.0, -1.0, 0.0), "right")
    assert m.side == "L"
    right = only_constraint(load_score(cs(orient(vector="lat(s)"))))
    assert right.vector == VAxis((0.0, -1.0, 0.0), "right")


def test_strong_side_defaults_to_right():
    data = drop(cs(place()), "strong_side")
    score = load_score(data)
    assert score.strong_side == "R"
    assert only_constraint(score).site == SiteRef("I_TIP_R")


# ---------------------------------------------------------------------------------------
# Expressions
# ---------------------------------------------------------------------------------------

SITES = {
    SiteRef("CH"): np.array([0.1, 0.0, 0.4]),
    SiteRef("I_TIP_R"): np.array([0.3, -0.2, 0.2]),
    SiteRef("ssp", locus=True): np.array([0.35, 0.0, 0.3]),
}
BONES = {
    (BoneRef("f_arm_R"), Axis.DIR): np.array([0.0, 0.0, -1.0]),
    (BoneRef("f_arm_R"), Axis.NRM): np.array([0.0, 1.0, 0.0]),
}


def _posture():
    """Kinematics on a posture whose sites and bone axes are SITES and BONES (written into
    the data: evaluation without Jacobians reads only these)."""
    model = load_model()
    data = mujoco.MjData(model)
    for ref, pos in SITES.items():
        data.site(ref.model_site(DEFAULT_MAP)).xpos[:] = pos
    b = BoneRef("f_arm_R").bone_map(DEFAULT_MAP)
    local = np.array([b.dir, b.nrm, np.cross(b.dir, b.nrm)])
    world = np.array([BONES[(BoneRef("f_arm_R"), Axis.DIR)], BONES[(BoneRef("f_arm_R"), Axis.NRM)]])
    world = np.vstack([world, np.cross(world[0], world[1])])
    data.body(b.body).xmat[:] = (world.T @ local).reshape(9)
    return Kinematics(model, data)


def eval_point(expr):
    return _posture().value(compile_point(expr, DEFAULT_MAP))


def eval_vector(expr):
    return _posture().value(compile_vector(expr, DEFAULT_MAP))


def load_vector(written, strong_side="R"):
    return only_constraint(load_score(cs(orient(vector=written), strong_side=strong_side))).vector


def load_point(written):
    return only_constraint(load_score(cs(place(at=written)))).at


@pytest.mark.parametrize(
    ("written", "value"),
    [
        ("@CH", [0.1, 0.0, 0.4]),
        ("^ssp", [0.35, 0.0, 0.3]),
        ([1, 2, 3], [1, 2, 3]),
        ({"translate": "@CH", "by": {"scale": "up", "by": 0.1}}, [0.1, 0.0, 0.5]),
        ({"translate": [0, 0, 0], "by": {"dir": "!f_arm(s)"}}, [0, 0, -1]),
        ({"mid": ["@CH", "@I_TIP(s)"]}, [0.2, -0.1, 0.3]),
        ({"mid": [{"mid": ["@CH", [0.1, 0, 0.4]]}, "^ssp"]}, [0.225, 0.0, 0.35]),
    ],
)
def test_point_expressions(written, value):
    np.testing.assert_allclose(eval_point(load_point(written)), value)


@pytest.mark.parametrize(
    ("written", "value"),
    [
        ("fwd", [1, 0, 0]),
        ("back", [-1, 0, 0]),
        ("left", [0, 1, 0]),
        ("right", [0, -1, 0]),
        ("up", [0, 0, 1]),
        ("down", [0, 0, -1]),
        ("lat(s)", [0, -1, 0]),
        ("lat(w)", [0, 1, 0]),
        ([0.5, 0, 0], [0.5, 0, 0]),
        ({"dir": "!f_arm(s)"}, [0, 0, -1]),
        ({"nrm": "!f_arm(s)"}, [0, 1, 0]),
        ({"opp": "up"}, [0, 0, -1]),
        ({"scale": "fwd", "by": 2}, [2, 0, 0]),
        ({"add": ["up", "fwd", [0, 0, 1]]}, [1, 0, 2]),
        ({"cross": ["fwd", "left"]}, [0, 0, 1]),
        ({"from": "@CH", "to": "@I_TIP(s)"}, [0.2, -0.2, -0.2]),
        ({"unit": [3, 0, 4]}, [0.6, 0, 0.8]),
        ({"unit": {"from": "@CH", "to": [0.1, 0, 0.9]}}, [0, 0, 1]),
    ],
)
def test_vector_expressions(written, value):
    np.testing.assert_allclose(eval_vector(load_vector(written)), value)


def test_lat_mirrors_with_strong_side():
    assert load_vector("lat(s)", "L") == VAxis((0.0, 1.0, 0.0), "left")
    assert load_vector("lat(w)", "L") == VAxis((0.0, -1.0, 0.0), "right")


def test_expression_records_and_dependencies():
    v = load_vector(
        {
            "add": [
                {"cross": [{"nrm": "!f_arm(s)"}, "up"]},
                {"from": "@CH", "to": {"mid": ["^ssp", "@CH"]}},
                {"opp": [1, 0, 0]},
            ]
        }
    )
    ch, ssp = SiteRef("CH"), SiteRef("ssp", locus=True)
    assert v == VAdd(
        (
            VCross(VBoneAxis(BoneRef("f_arm_R"), Axis.NRM), VAxis((0.0, 0.0, 1.0), "up")),
            VFrom(PSite(ch), PMid(PSite(ssp), PSite(ch))),
            VOpp(VLiteral((1.0, 0.0, 0.0))),
        )
    )
    assert depends_on_body(v)
    assert referenced_sites(v) == (ch, ssp)
    assert referenced_bones(v) == (BoneRef("f_arm_R"),)
    const = load_vector({"unit": {"scale": {"add": ["up", [1, 0, 0]]}, "by": 3}})
    assert const == VUnit(
        VScale(VAdd((VAxis((0.0, 0.0, 1.0), "up"), VLiteral((1.0, 0.0, 0.0)))), 3.0)
    )
    assert not depends_on_body(const)
    assert referenced_sites(const) == () and referenced_bones(const) == ()
    assert not depends_on_body(PLiteral((0.0, 0.0, 0.0)))
    assert depends_on_body(
        PTranslate(PLiteral((0.0, 0.0, 0.0)), VBoneAxis(BoneRef("head"), Axis.DIR))
    )


def test_unit_of_a_vector_that_becomes_zero_at_run_time_is_zero():
    v = VUnit(VFrom(PSite(SiteRef("CH")), PSite(SiteRef("CH"))))
    np.testing.assert_array_equal(eval_vector(v), np.zeros(3))


def test_direction_that_reads_the_body_is_not_checked_at_load_time():
    # {"from": "@CH", "to": "@CH"} is zero on every posture but reads the body: run time.
    v = load_vector({"from": "@CH", "to": "@CH"})
    assert depends_on_body(v)


# ---------------------------------------------------------------------------------------
# Bad input: exact messages (indices in messages are 1-based)
# ---------------------------------------------------------------------------------------

BAD = [
    (
        "format",
        top(format="azee"),
        'score: field \'format\': expected "azee-score", got "azee"',
        "",
        "format",
    ),
    (
        "version",
        top(version=2),
        "score: field 'version': unsupported version 2; this reader reads version 1",
        "",
        "version",
    ),
    (
        "version_str",
        top(version="1"),
        "score: field 'version': expected a number, got \"1\"",
        "",
        "version",
    ),
    (
        "top_unknown",
        dict(top(), strongside="R"),
        "score: unknown key 'strongside'; valid keys are format, version, strong_side, root (and x-* annotations); did you mean 'strong_side'?",
        "",
        "strongside",
    ),
    (
        "top_missing_root",
        drop(top(), "root"),
        "score: missing field 'root'; a score needs format, version, root",
        "",
        "root",
    ),
    ("top_not_object", [1], "score: expected a JSON object at the top level, got [1]", "", ""),
    (
        "strong_side",
        top(strong_side="s"),
        'score: field \'strong_side\': expected "R" or "L", got "s"',
        "",
        "strong_side",
    ),
    (
        "kind",
        kids(dict(cstr(), kind="cstrr")),
        "ROOT.K1: field 'kind': unknown block kind 'cstrr'; valid kinds are sync, cstr, hold, transpath; did you mean 'cstr'?",
        "ROOT.K1",
        "kind",
    ),
    (
        "block_unknown_key",
        kids(dict(drop(cstr(), "constraints"), constraint=[])),
        "ROOT.K1: unknown key 'constraint'; valid keys for a cstr block are name, kind, start, end, constraints (and x-* annotations); did you mean 'constraints'?",
        "ROOT.K1",
        "constraint",
    ),
    (
        "block_missing_end",
        kids(drop(cstr(), "end")),
        "ROOT.K1: missing field 'end'; a cstr block needs name, kind, start, end, constraints",
        "ROOT.K1",
        "end",
    ),
    (
        "start_string",
        kids(cstr(start="0.4")),
        "ROOT.K1: field 'start': expected a number, got \"0.4\"",
        "ROOT.K1",
        "start",
    ),
    (
        "start_bool",
        kids(cstr(start=True)),
        "ROOT.K1: field 'start': expected a number, got true",
        "ROOT.K1",
        "start",
    ),
    (
        "start_ge_end",
        kids(cstr(start=0.4, end=0.4)),
        "ROOT.K1: field 'end': end 0.4 is not after start 0.4; a block needs start < end",
        "ROOT.K1",
        "end",
    ),
    (
        "child_after_parent",
        kids(cstr(start=1, end=2.5)),
        "ROOT.K1: field 'end': 2.5 is after the end of its parent ROOT; a child's times are relative to its parent's start and lie within [0, 2]",
        "ROOT.K1",
        "end",
    ),
    (
        "child_before_parent",
        kids(cstr(start=-0.5, end=1)),
        "ROOT.K1: field 'start': -0.5 is before the start of its parent ROOT; a child's times are relative to its parent's start and lie within [0, 2]",
        "ROOT.K1",
        "start",
    ),
    (
        "dup",
        kids(cstr(), cstr(start=1, end=2)),
        "ROOT: child 2: field 'name': duplicate name 'K1' (child 1 has it too); sibling names must be unique",
        "ROOT",
        "name",
    ),
    (
        "name_missing",
        kids(drop(cstr(), "name")),
        "ROOT: child 1: missing field 'name'; a block needs name, kind, start, end",
        "ROOT",
        "name",
    ),
    (
        "name_dot",
        kids(cstr(name="A.B")),
        "ROOT: child 1: field 'name': block name 'A.B' contains '.'; block paths join names with '.', so use another character",
        "ROOT",
        "name",
    ),
    (
        "hold_none",
        kids(cstr(), {"name": "H", "kind": "hold", "start": 1, "end": 2, "of": "K3"}),
        "ROOT.H: field 'of': no sibling block named 'K3'; siblings are K1",
        "ROOT.H",
        "of",
    ),
    (
        "hold_self",
        kids(cstr(), {"name": "H", "kind": "hold", "start": 1, "end": 2, "of": "H"}),
        "ROOT.H: field 'of': 'H' is this hold itself; a hold names a sibling block: K1",
        "ROOT.H",
        "of",
    ),
    (
        "hold_early",
        kids(cstr(), {"name": "H", "kind": "hold", "start": 0.5, "end": 2, "of": "K1"}),
        "ROOT.H: field 'of': 'K1' ends at 1 s, after this hold starts at 0.5 s; a hold keeps the posture reached at the end of the block it holds, so it starts at or after that end",
        "ROOT.H",
        "of",
    ),
    (
        "site_unknown",
        cs(place(site="@I_TPI(s)")),
        "ROOT.K1: constraint 1 (place): unknown site '@I_TPI(s)'; did you mean '@I_TIP(s)'? (azee-mj sites lists all)",
        "ROOT.K1",
        "site",
    ),
    (
        "site_unknown_at",
        cs(place(at={"translate": "@CHH", "by": "up"})),
        "ROOT.K1: constraint 1 (place): field 'at.translate': unknown site '@CHH'; did you mean '@CH'? (azee-mj sites lists all)",
        "ROOT.K1",
        "at.translate",
    ),
    (
        "site_stem_nosuggest",
        cs(place(site="@QQQQ(s)")),
        "ROOT.K1: constraint 1 (place): unknown site '@QQQQ(s)'; azee-mj sites lists all valid names",
        "ROOT.K1",
        "site",
    ),
    (
        "site_phalanx",
        cs(place(site="@I_KN(s,4)")),
        "ROOT.K1: constraint 1 (place): phalanx '4' in '@I_KN(s,4)' is not 1, 2 or 3; phalanges are numbered 1 (proximal) to 3 (distal)",
        "ROOT.K1",
        "site",
    ),
    (
        "site_phalanx_missing",
        cs(place(site="@I_KN(s)")),
        "ROOT.K1: constraint 1 (place): site 'I_KN' needs a side and a phalanx number; write e.g. '@I_KN(s,1)' (1 proximal to 3 distal)",
        "ROOT.K1",
        "site",
    ),
    (
        "site_phalanx_extra",
        cs(place(site="@I_TIP(s,2)")),
        "ROOT.K1: constraint 1 (place): site 'I_TIP' takes no phalanx number; write '@I_TIP(s)'",
        "ROOT.K1",
        "site",
    ),
    (
        "site_midline_side",
        cs(place(site="@FH(s)")),
        "ROOT.K1: constraint 1 (place): site 'FH' is on the midline and takes no side; write '@FH'",
        "ROOT.K1",
        "site",
    ),
    (
        "site_lateral_noside",
        cs(place(site="@EL")),
        "ROOT.K1: constraint 1 (place): site 'EL' needs a side; write '@EL(s)', '@EL(w)', '@EL(R)' or '@EL(L)'",
        "ROOT.K1",
        "site",
    ),
    (
        "site_side",
        cs(place(site="@EL(x)")),
        "ROOT.K1: constraint 1 (place): unknown side 'x' in '@EL(x)'; valid sides are s, w, L, R",
        "ROOT.K1",
        "site",
    ),
    (
        "site_malformed",
        cs(place(site="@EL(s")),
        "ROOT.K1: constraint 1 (place): malformed site reference '@EL(s'; write '@STEM', '@STEM(side)' or '@STEM(side,n)', e.g. '@FH', '@I_TIP(s)', '@I_KN(s,2)'",
        "ROOT.K1",
        "site",
    ),
    (
        "site_locus",
        cs(place(site="^ssp")),
        "ROOT.K1: constraint 1 (place): '^ssp' is a signing-space locus, not a body site; a place moves a body site ('@...')",
        "ROOT.K1",
        "site",
    ),
    (
        "locus_unknown",
        cs(place(at="^spp")),
        "ROOT.K1: constraint 1 (place): field 'at': unknown locus '^spp'; valid loci are ^ssp, ^Rssp, ^Lssp; did you mean '^ssp'?",
        "ROOT.K1",
        "at",
    ),
    (
        "bone_unknown",
        cs(orient(bone="!farm(s)")),
        "ROOT.K1: constraint 1 (orient): unknown bone '!farm(s)'; did you mean '!f_arm(s)'? (azee-mj sites lists all)",
        "ROOT.K1",
        "bone",
    ),
    (
        "bone_stem",
        cs(orient(bone="!foo")),
        "ROOT.K1: constraint 1 (orient): unknown bone '!foo'; azee-mj sites lists all valid names",
        "ROOT.K1",
        "bone",
    ),
    (
        "bone_phalanx",
        cs(orient(bone="!index(s,0)")),
        "ROOT.K1: constraint 1 (orient): phalanx '0' in '!index(s,0)' is not 1, 2 or 3; phalanges are numbered 1 (proximal) to 3 (distal)",
        "ROOT.K1",
        "bone",
    ),
    (
        "bone_midline_side",
        cs(orient(bone="!head(s)")),
        "ROOT.K1: constraint 1 (orient): bone 'head' is on the midline and takes no side; write '!head'",
        "ROOT.K1",
        "bone",
    ),
    (
        "bone_noside",
        cs(orient(bone="!palm")),
        "ROOT.K1: constraint 1 (orient): bone 'palm' needs a side; write '!palm(s)', '!palm(w)', '!palm(R)' or '!palm(L)'",
        "ROOT.K1",
        "bone",
    ),
    (
        "bone_noprefix",
        cs(orient(bone="f_arm(s)")),
        "ROOT.K1: constraint 1 (orient): expected a bone such as '!f_arm(s)', got \"f_arm(s)\"",
        "ROOT.K1",
        "bone",
    ),
    (
        "morph_unknown",
        cs({"type": "morph", "id": "fistt", "weight": 1}),
        "ROOT.K1: constraint 1 (morph): field 'id': unknown morph 'fistt'; valid ids are index_bend, index_hook, middle_bend, middle_hook, ring_bend, ring_hook, little_bend, little_hook, ..., and 114 more; did you mean 'fist'?",
        "ROOT.K1",
        "id",
    ),
    (
        "morph_side_unsided",
        cs({"type": "morph", "id": "jaw_open", "weight": 1, "side": "s"}),
        "ROOT.K1: constraint 1 (morph): field 'side': morph 'jaw_open' has no sides; remove 'side'",
        "ROOT.K1",
        "side",
    ),
    (
        "morph_side_bad",
        cs({"type": "morph", "id": "fist", "weight": 1, "side": "right"}),
        "ROOT.K1: constraint 1 (morph): field 'side': unknown side 'right'; valid sides are s, w, L, R",
        "ROOT.K1",
        "side",
    ),
    (
        "ctype",
        cs({"type": "plcae", "site": "@CH", "at": "@CH"}),
        "ROOT.K1: constraint 1: field 'type': unknown constraint type 'plcae'; valid types are place, orient, morph, look, trill; did you mean 'place'?",
        "ROOT.K1",
        "type",
    ),
    (
        "ctype_missing",
        cs({"site": "@CH"}),
        "ROOT.K1: constraint 1: missing field 'type'; valid types are place, orient, morph, look, trill",
        "ROOT.K1",
        "type",
    ),
    (
        "c_unknown_key",
        cs(place(tool=0.1)),
        "ROOT.K1: constraint 1 (place): unknown key 'tool'; valid keys for a place constraint are type, site, at, tol (and x-* annotations); did you mean 'tol'?",
        "ROOT.K1",
        "tool",
    ),
    (
        "orient_tol",
        cs(orient(tol=0.1)),
        "ROOT.K1: constraint 1 (orient): unknown key 'tol'; valid keys for an orient constraint are type, bone, axis, rel, vector, tol_deg (and x-* annotations); did you mean 'tol_deg'?",
        "ROOT.K1",
        "tol",
    ),
    (
        "axis",
        cs(orient(axis="dri")),
        "ROOT.K1: constraint 1 (orient): field 'axis': unknown axis 'dri'; valid axes are dir, nrm; did you mean 'dir'?",
        "ROOT.K1",
        "axis",
    ),
    (
        "rel",
        cs(orient(rel="paralel")),
        "ROOT.K1: constraint 1 (orient): field 'rel': unknown relation 'paralel'; valid relations are along, opp, perp",
        "ROOT.K1",
        "rel",
    ),
    (
        "tol_zero",
        cs(place(tol=0)),
        "ROOT.K1: constraint 1 (place): field 'tol': must be positive, got 0",
        "ROOT.K1",
        "tol",
    ),
    (
        "tol_deg_neg",
        cs(orient(tol_deg=-1)),
        "ROOT.K1: constraint 1 (orient): field 'tol_deg': must be positive, got -1",
        "ROOT.K1",
        "tol_deg",
    ),
    (
        "freq",
        cs(
            {
                "type": "trill",
                "site": "@I_TIP(s)",
                "vector": "up",
                "amplitude": 0.01,
                "frequency": 0,
            }
        ),
        "ROOT.K1: constraint 1 (trill): field 'frequency': must be positive, got 0",
        "ROOT.K1",
        "frequency",
    ),
    (
        "amp",
        cs(
            {
                "type": "trill",
                "site": "@I_TIP(s)",
                "vector": "up",
                "amplitude": -0.01,
                "frequency": 4,
            }
        ),
        "ROOT.K1: constraint 1 (trill): field 'amplitude': must be positive, got -0.01",
        "ROOT.K1",
        "amplitude",
    ),
    (
        "amp_deg",
        cs(
            {
                "type": "trill",
                "bone": "!palm(s)",
                "vector": "up",
                "amplitude_deg": 0,
                "frequency": 4,
            }
        ),
        "ROOT.K1: constraint 1 (trill): field 'amplitude_deg': must be positive, got 0",
        "ROOT.K1",
        "amplitude_deg",
    ),
    (
        "trill_wrong_amp",
        cs(
            {"type": "trill", "bone": "!palm(s)", "vector": "up", "amplitude": 0.01, "frequency": 4}
        ),
        "ROOT.K1: constraint 1 (trill): field 'amplitude': a bone trill takes 'amplitude_deg', not 'amplitude'; give 'amplitude_deg' in degrees",
        "ROOT.K1",
        "amplitude",
    ),
    (
        "trill_both",
        cs(
            {
                "type": "trill",
                "site": "@I_TIP(s)",
                "bone": "!palm(s)",
                "vector": "up",
                "amplitude": 0.01,
                "frequency": 4,
            }
        ),
        "ROOT.K1: constraint 1 (trill): both 'site' and 'bone' given; a trill moves a site (with 'amplitude' [m]) or turns a bone (with 'amplitude_deg')",
        "ROOT.K1",
        "",
    ),
    (
        "trill_none",
        cs({"type": "trill", "vector": "up", "amplitude": 0.01, "frequency": 4}),
        "ROOT.K1: constraint 1 (trill): missing field 'site' or 'bone'; a trill moves a site (with 'amplitude' [m]) or turns a bone (with 'amplitude_deg')",
        "ROOT.K1",
        "",
    ),
    (
        "trill_zero",
        cs(
            {
                "type": "trill",
                "site": "@I_TIP(s)",
                "vector": [0, 0, 0],
                "amplitude": 0.01,
                "frequency": 4,
            }
        ),
        "ROOT.K1: constraint 1 (trill): field 'vector': zero direction [0, 0, 0]; give a vector of non-zero length",
        "ROOT.K1",
        "vector",
    ),
    (
        "turns",
        tp({"shape": "circle", "center": "@CH", "turns": 0}),
        "ROOT.T: field 'path.turns': must be positive, got 0",
        "ROOT.T",
        "path.turns",
    ),
    (
        "shape",
        tp({"shape": "arcc"}),
        "ROOT.T: field 'path.shape': unknown shape 'arcc'; valid shapes are straight, arc, circle; did you mean 'arc'?",
        "ROOT.T",
        "path.shape",
    ),
    (
        "path_key",
        tp({"shape": "arc", "bulg": "up"}),
        "ROOT.T: field 'path': unknown key 'bulg'; valid keys for an arc path are shape, bulge (and x-* annotations); did you mean 'bulge'?",
        "ROOT.T",
        "path.bulg",
    ),
    (
        "bulge_zero",
        tp({"shape": "arc", "bulge": {"scale": "up", "by": 0}}),
        'ROOT.T: field \'path.bulge\': zero direction {"scale": "up", "by": 0}; give a vector of non-zero length',
        "ROOT.T",
        "path.bulge",
    ),
    (
        "normal_zero",
        tp({"shape": "circle", "center": "@CH", "normal": {"add": ["up", "down"]}}),
        'ROOT.T: field \'path.normal\': zero direction {"add": ["up", "down"]}; give a vector of non-zero length',
        "ROOT.T",
        "path.normal",
    ),
    (
        "zero_lit",
        cs(orient(vector=[0, 0, 0])),
        "ROOT.K1: constraint 1 (orient): field 'vector': zero direction [0, 0, 0]; give a vector of non-zero length",
        "ROOT.K1",
        "vector",
    ),
    (
        "zero_scale",
        cs(orient(vector={"scale": "up", "by": 0})),
        'ROOT.K1: constraint 1 (orient): field \'vector\': zero direction {"scale": "up", "by": 0}; give a vector of non-zero length',
        "ROOT.K1",
        "vector",
    ),
    (
        "zero_add",
        cs(orient(vector={"add": ["up", "down"]})),
        'ROOT.K1: constraint 1 (orient): field \'vector\': zero direction {"add": ["up", "down"]}; give a vector of non-zero length',
        "ROOT.K1",
        "vector",
    ),
    (
        "zero_unit",
        cs(place(at={"translate": "@CH", "by": {"unit": [0, 0, 0]}})),
        "ROOT.K1: constraint 1 (place): field 'at.by.unit': cannot normalise the zero vector [0, 0, 0]; give a vector of non-zero length",
        "ROOT.K1",
        "at.by.unit",
    ),
    (
        "vec_unknown",
        cs(orient(vector="forward")),
        "ROOT.K1: constraint 1 (orient): field 'vector': unknown direction 'forward'; valid directions are fwd, back, left, right, up, down, lat(s), lat(w); did you mean 'fwd'?",
        "ROOT.K1",
        "vector",
    ),
    (
        "vec_point",
        cs(orient(vector="@CH")),
        "ROOT.K1: constraint 1 (orient): field 'vector': '@CH' is a point, not a vector; use {\"from\": P, \"to\": Q} for the vector between two points",
        "ROOT.K1",
        "vector",
    ),
    (
        "lat_bad",
        cs(orient(vector="lat(x)")),
        "ROOT.K1: constraint 1 (orient): field 'vector': unknown side 'x' in 'lat(x)'; write lat(s) or lat(w), or left / right",
        "ROOT.K1",
        "vector",
    ),
    (
        "point_dir",
        cs(place(at="up")),
        "ROOT.K1: constraint 1 (place): field 'at': 'up' is a direction, not a point; use [x, y, z] or {\"translate\": P, \"by\": V}",
        "ROOT.K1",
        "at",
    ),
    (
        "point_form",
        cs(place(at={"translat": "@CH", "by": "up"})),
        'ROOT.K1: constraint 1 (place): field \'at\': unknown key \'translat\' in a point; expected a point ("@SITE", "^locus", [x, y, z], {"translate": P, "by": V} or {"mid": [P, Q]}); did you mean \'translate\'?',
        "ROOT.K1",
        "at",
    ),
    (
        "point_incomplete",
        cs(place(at={"translate": "@CH"})),
        'ROOT.K1: constraint 1 (place): field \'at\': \'translate\' needs \'by\'; expected a point ("@SITE", "^locus", [x, y, z], {"translate": P, "by": V} or {"mid": [P, Q]})',
        "ROOT.K1",
        "at",
    ),
    (
        "point_mix",
        cs(place(at={"translate": "@CH", "mid": ["@CH", "@FH"]})),
        'ROOT.K1: constraint 1 (place): field \'at\': {"translate": "@CH", "mid": ["@CH", "@FH"]} mixes the forms \'translate\' and \'mid\'; expected a point ("@SITE", "^locus", [x, y, z], {"translate": P, "by": V} or {"mid": [P, Q]})',
        "ROOT.K1",
        "at",
    ),
    (
        "mid_len",
        cs(place(at={"mid": ["@CH"]})),
        "ROOT.K1: constraint 1 (place): field 'at.mid': expected 2 points, got [\"@CH\"]",
        "ROOT.K1",
        "at.mid",
    ),
    (
        "mid_inner",
        cs(place(at={"mid": ["@CH", "@FH(s)"]})),
        "ROOT.K1: constraint 1 (place): field 'at.mid[2]': site 'FH' is on the midline and takes no side; write '@FH'",
        "ROOT.K1",
        "at.mid[2]",
    ),
    (
        "lit_len",
        cs(place(at=[1, 2])),
        "ROOT.K1: constraint 1 (place): field 'at': expected 3 numbers [x, y, z], got [1, 2]",
        "ROOT.K1",
        "at",
    ),
    (
        "cross_len",
        cs(orient(vector={"cross": ["up"]})),
        "ROOT.K1: constraint 1 (orient): field 'vector.cross': expected 2 vectors, got [\"up\"]",
        "ROOT.K1",
        "vector.cross",
    ),
    (
        "add_empty",
        cs(orient(vector={"add": []})),
        "ROOT.K1: constraint 1 (orient): field 'vector.add': expected a list of one or more vectors, got []",
        "ROOT.K1",
        "vector.add",
    ),
    (
        "add_inner",
        cs(orient(vector={"add": ["up", "upp"]})),
        "ROOT.K1: constraint 1 (orient): field 'vector.add[2]': unknown direction 'upp'; valid directions are fwd, back, left, right, up, down, lat(s), lat(w); did you mean 'up'?",
        "ROOT.K1",
        "vector.add[2]",
    ),
    (
        "dir_bone",
        cs(orient(vector={"dir": "!farm(w)"})),
        "ROOT.K1: constraint 1 (orient): field 'vector.dir': unknown bone '!farm(w)'; did you mean '!f_arm(w)'? (azee-mj sites lists all)",
        "ROOT.K1",
        "vector.dir",
    ),
    (
        "from_to",
        cs(orient(vector={"from": "@CH", "to": "@FHH"})),
        "ROOT.K1: constraint 1 (orient): field 'vector.to': unknown site '@FHH'; did you mean '@FH'? (azee-mj sites lists all)",
        "ROOT.K1",
        "vector.to",
    ),
    (
        "scale_by",
        cs(orient(vector={"scale": "up", "by": "2"})),
        "ROOT.K1: constraint 1 (orient): field 'vector.by': expected a number, got \"2\"",
        "ROOT.K1",
        "vector.by",
    ),
    (
        "constraints_type",
        kids(cstr() | {"constraints": {}}),
        "ROOT.K1: field 'constraints': expected a list of constraints, got {}",
        "ROOT.K1",
        "constraints",
    ),
    (
        "children_type",
        top(root={"name": "ROOT", "kind": "sync", "start": 0, "end": 2, "children": {}}),
        "ROOT: field 'children': expected a list of blocks, got {}",
        "ROOT",
        "children",
    ),
    (
        "transpath_locus",
        tp({"shape": "straight"}, site="^ssp"),
        "ROOT.T: field 'site': '^ssp' is a signing-space locus, not a body site; a transpath moves a body site ('@...')",
        "ROOT.T",
        "site",
    ),
    (
        "root_hold",
        top(root={"name": "ROOT", "kind": "hold", "start": 0, "end": 2, "of": "X"}),
        "ROOT: field 'of': no sibling block named 'X'; the root block has no siblings to hold",
        "ROOT",
        "of",
    ),
    (
        "nested",
        kids(
            {
                "name": "S",
                "kind": "sync",
                "start": 0.5,
                "end": 1.5,
                "children": [cstr(start=0.5, end=1.2)],
            }
        ),
        "ROOT.S.K1: field 'end': 1.2 is after the end of its parent ROOT.S; a child's times are relative to its parent's start and lie within [0, 1]",
        "ROOT.S.K1",
        "end",
    ),
    (
        "nan",
        kids(cstr(end=float("nan"))),
        "ROOT.K1: field 'end': expected a finite number, got NaN",
        "ROOT.K1",
        "end",
    ),
    (
        "constraint_notobj",
        cs("place"),
        'ROOT.K1: constraint 1: expected a constraint (a JSON object), got "place"',
        "ROOT.K1",
        "",
    ),
]


@pytest.mark.parametrize(
    ("data", "message", "path", "field"), [c[1:] for c in BAD], ids=[c[0] for c in BAD]
)
def test_bad_input_is_rejected_with_one_exact_message(data, message, path, field):
    with pytest.raises(ScoreError) as info:
        load_score(data)
    assert str(info.value) == message
    assert (info.value.path, info.value.field) == (path, field)
    assert isinstance(info.value, AzeeError)
    assert len(message.splitlines()) <= 4


def test_long_lists_are_abbreviated():
    with pytest.raises(ScoreError, match=r"\.\.\., and 114 more; did you mean 'fist'\?$"):
        load_score(cs({"type": "morph", "id": "fistt", "weight": 1}))


def test_file_errors_name_the_file(tmp_path):
    missing = tmp_path / "missing.json"
    with pytest.raises(ScoreError, match=r"missing\.json: cannot read the score: "):
        load_score(missing)
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "azee-score",\n "version": 1,,}')
    with pytest.raises(ScoreError) as info:
        load_score(bad)
    assert str(info.value) == (
        f"{bad}: line 2 column 15: invalid JSON: Expecting property name enclosed in double quotes"
    )
    dup = tmp_path / "dup.json"
    dup.write_text('{"format": "azee-score", "format": "azee-score"}')
    with pytest.raises(ScoreError) as info:
        load_score(dup)
    assert str(info.value) == (
        f"{dup}: invalid score JSON: key 'format' appears twice in one object; "
        "each key may appear once"
    )
    nan = tmp_path / "nan.json"
    nan.write_text('{"version": NaN}')
    with pytest.raises(ScoreError) as info:
        load_score(nan)
    assert str(info.value) == f"{nan}: invalid JSON: NaN is not a JSON number; use a finite number"


def test_example_file_errors_are_validated_like_dicts(tmp_path):
    data = json.loads((DATA / "good.json").read_text())
    data["root"]["children"][1]["constraints"][0]["site"] = "@T_TPI(s)"
    path = tmp_path / "typo.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ScoreError) as info:
        load_score(path)
    assert str(info.value) == (
        "GOOD.K1: constraint 1 (place): unknown site '@T_TPI(s)'; did you mean '@T_TIP(s)'? "
        "(azee-mj sites lists all)"
    )


# ---------------------------------------------------------------------------------------
# Property: random valid nestings keep every child inside its parent
# ---------------------------------------------------------------------------------------


@st.composite
def blocks(draw, depth=0, name="ROOT", span=None):
    """A random valid block as JSON with times relative to its parent of length ``span``."""
    if span is None:
        start = draw(st.floats(-5, 5, allow_nan=False))
        dur = draw(st.floats(0.01, 10))
    else:
        a = draw(st.floats(0, span))
        b = draw(st.floats(0, span))
        start, end = min(a, b), max(a, b)
        if end - start < 1e-6:
            start, end = 0.0, span
        dur = end - start
    block = {"name": name, "start": start, "end": start + dur}
    if span is not None:
        block["end"] = end
    if depth < 3 and draw(st.booleans()):
        n = draw(st.integers(0, 4))
        block["kind"] = "sync"
        block["children"] = [
            draw(blocks(depth=depth + 1, name=f"B{i}", span=block["end"] - block["start"]))
            for i in range(n)
        ]
    else:
        block["kind"] = "cstr"
        block["constraints"] = [{"type": "morph", "id": "fist", "weight": 1.0, "side": "s"}]
    return block


def _check_nesting(block: Block) -> None:
    for child in block.children:
        assert block.start - 1e-9 <= child.start < child.end <= block.end + 1e-9
        _check_nesting(child)


@settings(max_examples=60, deadline=None)
@given(blocks())
def test_random_valid_nestings_load_and_children_lie_inside_parents(root):
    if root["end"] <= root["start"]:
        return
    score = load_score(top(root=root))
    assert score.root.start == 0.0
    # Times are resolved to the microsecond.
    assert score.root.end == exact_time(root["end"] - root["start"])
    _check_nesting(score.root)
    assert len({b.path for b in score.blocks()}) == len(list(score.blocks()))


# ---------------------------------------------------------------------------------------
# The parts of the loader, called directly
# ---------------------------------------------------------------------------------------


def test_child_span_is_on_the_microsecond_grid_and_inside_its_parent():
    # 1.0 + 1.4 is 2.4000000000000004 in floating point; the span is the time 2.4 itself
    assert child_span(0.4, 1.4, 1.0, 2.4) == (1.4, 2.4)
    assert child_span(0.4, 1.4, 1.0, 2.4)[1] == 2.4 == 120 / 50
    # written a hair outside the parent (within the load-time slack): kept inside it
    assert child_span(-1e-10, 1.0 + 1e-10, 3.0, 4.0) == (3.0, 4.0)
    assert child_span(0.5, 2.0, 1.0, None) == (1.5, 3.0)
    assert root_span(1.25, 3.75) == (0.0, 2.5)


def test_expression_reader_reads_the_grammar_and_names_the_field():
    refs = References(DEFAULT_MAP, strong="L")
    reader = ExpressionReader(refs)
    loc = Loc("sign", "constraint 1 (place)")
    p = reader.point(loc, "at", {"translate": [0, 0, 1], "by": {"scale": "lat(s)", "by": 2}})
    assert p == PTranslate(PLiteral((0.0, 0.0, 1.0)), VScale(VAxis((0.0, 1.0, 0.0), "left"), 2.0))
    assert reader.vector(loc, "v", "lat(w)").name == "right"
    with pytest.raises(ScoreError) as e:
        reader.vector(loc, "v", {"opp": "up", "unit": "up"})
    assert str(e.value) == (
        "sign: constraint 1 (place): field 'v': "
        '{"opp": "up", "unit": "up"} mixes the forms \'opp\' and \'unit\'; expected ' + VECTOR_DESC
    )
    with pytest.raises(ScoreError) as e:
        reader.direction(loc, "v", {"add": ["up", "down"]})
    assert str(e.value) == (
        'sign: constraint 1 (place): field \'v\': zero direction {"add": ["up", "down"]}; '
        "give a vector of non-zero length"
    )


def _blocks(*spans: tuple[str, float, float, str | None]) -> tuple[Block, ...]:
    return tuple(
        Block(
            name=n,
            path=f"s.{n}",
            kind=BlockKind.HOLD if of else BlockKind.CSTR,
            start=a,
            end=b,
            hold_of=f"s.{of}" if of else None,
        )
        for n, a, b, of in spans
    )


def test_check_holds_names_the_hold_the_block_it_holds_and_the_times():
    check_holds("s", _blocks(("a", 1.0, 2.0, None), ("h", 2.0, 3.0, "a")), 1.0)
    with pytest.raises(ScoreError) as e:
        check_holds("s", _blocks(("a", 1.0, 2.5, None), ("h", 2.0, 3.0, "a")), 1.0)
    assert str(e.value) == (
        "s.h: field 'of': 'a' ends at 1.5 s, after this hold starts at 1 s; a hold keeps the "
        "posture reached at the end of the block it holds, so it starts at or after that end"
    )
    with pytest.raises(ScoreError) as e:
        check_holds("s", _blocks(("a", 1.0, 2.0, None), ("h", 2.0, 3.0, "b")), 1.0)
    assert str(e.value) == "s.h: field 'of': no sibling block named 'b'; siblings are a"
