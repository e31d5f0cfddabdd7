"""`make demo` on a tiny scene produces every section; a failing method is reported, not fatal."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("bpy")

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    env = dict(os.environ)
    # 20000 texels is beyond the GPU limit: every method must fail at that size with a reason
    cmd = [sys.executable, "-m", "bench.report", "--quick", "--scene", "tiny", "--methods", "uniform,lispsm",
           "--sizes", "128,20000", "--frames", "2", "--resolution", "64x48", "--eevee-samples", "1",
           "--out", str(out), "--readme-picture", str(out / "comparison.png")]
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return out, proc.stdout


def test_every_section_in_both_documents(report):
    from bench.report.document import SECTIONS
    out, _ = report
    html = (out / "report.html").read_text()
    md = (out / "report.md").read_text()
    assert "Scene: tiny" in html and "## Scene: tiny" in md
    assert "<h2>Summary</h2>" in html and "## Summary" in md
    for section in SECTIONS:
        assert f"<h3>{section}</h3>" in html
        assert f"### {section}" in md
    for png in ("renders", "shadow_maps", "footprint", "errors", "speed_error"):
        path = out / "tiny" / f"{png}.png"
        assert path.stat().st_size > 1000, path
        assert f"tiny/{png}.png" in html and f"tiny/{png}.png" in md
    assert (out / "comparison.png").stat().st_size > 1000
    assert "figure failed" not in html


def test_table_has_methods_peers_limit_and_failures(report):
    out, stdout = report
    data = json.loads((out / "report.json").read_text())
    scene = data["scenes"][0]
    assert scene["status"] == "ok"
    assert scene["n_min"] > 0
    ok = [m for m in scene["methods"] if m["status"] == "ok"]
    failed = [m for m in scene["methods"] if m["status"] == "failed"]
    assert {m["method"] for m in ok} == {"uniform", "lispsm"} and all(m["size"] == 128 for m in ok)
    assert {m["method"] for m in failed} == {"uniform", "lispsm"} and all(m["size"] == 20000 for m in failed)
    assert all("16384" in m["reason"] for m in failed)
    for m in ok:
        assert 0 <= m["errors"]["error_rate"] <= 1
        assert m["errors"]["valid"] > 0
        assert m["footprint"]["max"] > 0 and 0 <= m["footprint"]["frac_above_1"] <= 1
        assert m["m_min"] > 0 and m["max_over_limit"] > 0
        assert "rate" in m["flicker"]
        assert {"cpu_setup", "depth_pass", "shading"} <= set(m["timings"])
    peers = {p["method"]: p for p in scene["peers"]}
    assert set(peers) == {"eevee", "cycles"}
    for p in peers.values():
        assert p["status"] == "ok", p.get("reason")
        assert p["total_ms"] > 0
    # Cycles with one delta light and no bounces is exact: it agrees with the ray-cast truth
    assert peers["cycles"]["errors"]["error_rate"] < 0.01
    html = (out / "report.html").read_text()
    assert html.count("class='failed'") == 2 and "16384" in html
    assert "tiny: uniform @ 128" in stdout            # progress is printed


def test_pareto_front_keeps_only_undominated_points():
    from bench.report.figures import pareto_front
    pts = [(10, 5.0), (20, 1.0), (15, 6.0), (5, 9.0), (30, 1.0), (25, 0.5)]
    assert sorted(pareto_front(pts)) == [0, 1, 3, 5]
