"""Every example runs in a short setting and writes its PNG (STYLE.md §11)."""

from __future__ import annotations

import os
import pathlib
import runpy
import subprocess
import sys

import pytest

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples"


@pytest.mark.parametrize("script, args", [
    ("heave_bump.py", ["--duration", "4", "--frequency", "1"]),
    ("seed_single_actuator.py", ["--duration", "6"]),
    ("buffered_compensation.py", ["--duration", "10"]),
    ("servo_cylinder.py", ["--only", "3V_s1"]),
    ("vehicle_cueing.py", ["--manoeuvre", "lane-change"]),
    ("cueing_comparison.py", ["--manoeuvres", "road-bumps", "--iterations", "1"]),
    ("tuned_compensation.py", ["--dofs", "heave", "--duration", "12", "--machines", "", "--jobs", "1"]),
])
def test_example_runs(script, args, tmp_path):
    out = tmp_path / "out.png"
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, str(EXAMPLES / script), *args, "--out", str(out)],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert out.read_bytes()[:4] == b"\x89PNG"
    assert "wrote" in proc.stdout


@pytest.mark.parametrize("script", sorted(p.name for p in EXAMPLES.glob("*.py")))
def test_every_example_loads(script):
    """Every example's module-level code runs (its imports, its cases' RunConfigs): those too long for the
    suite (the calibrations, the proof) are not run above, and a change of an API they build at import time
    (validate_generated_logs.py's RunConfig, the hexapod example's test imports) failed only when a user ran
    them."""
    namespace = runpy.run_path(str(EXAMPLES / script), run_name="example")
    assert callable(namespace.get("main")), f"{script} has no main()"
