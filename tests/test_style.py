"""The code style of the repository: ``ruff format`` and ``ruff check`` (configured in
pyproject.toml) are clean on the package, the benchmarks, the tests and the tools."""

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PATHS = ["azee_mj", "bench", "tests", "tools"]


def _ruff() -> list[str]:
    if importlib.util.find_spec("ruff") is not None:
        return [sys.executable, "-m", "ruff"]
    if exe := shutil.which("ruff"):
        return [exe]
    pytest.skip("ruff is not installed (it comes with the [test] extra: pip install azee_mj[test])")


@pytest.mark.parametrize(
    "command", [["format", "--check"], ["check"]], ids=["ruff-format", "ruff-check"]
)
def test_ruff_is_clean(command):
    done = subprocess.run(
        [*_ruff(), *command, *PATHS], cwd=ROOT, capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stdout + done.stderr
