"""The machine a benchmark ran on: CPU, cores, versions and date (for the results files)."""

from __future__ import annotations

import datetime
import importlib.metadata as md
import json
import os
import platform
import sys
from pathlib import Path

import mujoco
import numpy as np


def _version(package: str) -> str | None:
    try:
        return md.version(package)
    except md.PackageNotFoundError:
        return None


def cpu() -> str:
    """The CPU model name (``/proc/cpuinfo``), or what ``platform`` knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def machine(**extra) -> dict:
    """CPU, cores, Python and library versions, platform and date, plus ``extra``."""
    return {
        "cpu": cpu(),
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
        "mink": _version("mink"),
        "daqp": _version("daqp"),
        "platform": platform.platform(),
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        **extra,
    }


def write_result(out: Path, doc: dict) -> None:
    """Write a results document ``doc`` as JSON to ``out`` whole or not at all (through a
    temporary file renamed over it), and say where on stderr."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(json.dumps(doc, indent=1) + "\n")
    tmp.replace(out)
    print(f"wrote {out}", file=sys.stderr)
