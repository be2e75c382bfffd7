"""A few hundred seeded mutants of the bundled examples through ``azee-mj realize``, and of
a rollout file through ``azee-mj check``: no traceback, no hang, no NaN output (the
1,000-mutant run is ``bench/fuzz.py``)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location(
    "bench_fuzz", Path(__file__).resolve().parent.parent / "bench" / "fuzz.py"
)
fuzz = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fuzz)

COUNT = 250


@pytest.mark.fuzz
def test_mutants_end_in_a_rollout_or_one_clean_message(tmp_path):
    outcomes, failures = {}, []
    for label, m in fuzz.mutants(COUNT, seed=14):
        outcome, detail = fuzz.run_one(m, tmp_path, fps=10.0, timeout=60.0)
        outcomes[outcome] = outcomes.get(outcome, 0) + 1
        if outcome not in ("ok", "rejected"):
            failures.append(f"{label}: {outcome}: {detail}")
    assert failures == []
    # The mutator reaches both ends: scores that still realize and scores that are refused.
    assert outcomes.get("ok", 0) >= 10 and outcomes.get("rejected", 0) >= 100, outcomes


@pytest.mark.fuzz
def test_damaged_rollouts_end_in_a_check_or_one_clean_message(tmp_path):
    outcomes, failures = {}, []
    for label, m in fuzz.rollout_mutants(200, seed=14):
        outcome, detail = fuzz.check_one(m, tmp_path)
        outcomes[outcome] = outcomes.get(outcome, 0) + 1
        if outcome not in ("ok", "rejected"):
            failures.append(f"{label}: {outcome}: {detail}")
    assert failures == []
    assert outcomes.get("ok", 0) >= 20 and outcomes.get("rejected", 0) >= 100, outcomes


@pytest.mark.fuzz
def test_hostile_names_in_pages_and_reports_and_deep_nesting(tmp_path):
    pytest.importorskip("pygltflib", reason="the player needs azee_mj[export]")
    pytest.importorskip("matplotlib", reason="the report needs azee_mj[plot]")
    outcomes, failures = fuzz.names_round(20, 3, 27, tmp_path)
    assert failures == []
    assert outcomes["page:ok"] == 20 and outcomes["report:ok"] + outcomes["report:rejected"] == 3
    assert outcomes["depth:ok"] >= 6 and outcomes["depth:rejected"] >= 8, outcomes


@pytest.mark.fuzz
def test_hostile_manifests_read_back_as_rows_or_one_clean_error(tmp_path):
    outcomes, failures = fuzz.manifests_round(150, 27, tmp_path)
    assert failures == []
    assert outcomes["ok"] >= 50, outcomes
