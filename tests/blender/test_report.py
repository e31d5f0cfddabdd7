"""`make demo` on a tiny scene produces every section, every key and the overlay
snapshots; timed points are medians with min and max; a failing method is
reported, not fatal; bad arguments are refused and leave the last report."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("bpy")

ROOT = Path(__file__).resolve().parents[2]
BASE = [sys.executable, "-m", "bench.report", "--quick", "--scene", "tiny", "--frames", "2", "--resolution", "64x48",
        "--repeats", "3", "--peer-repeats", "2"]


def _run(args, out, timeout=600):
    return subprocess.run(BASE + args + ["--out", str(out)], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    # 20000 texels is beyond the GPU limit: every method must fail at that size with a reason
    proc = _run(["--methods", "uniform,lispsm", "--sizes", "128,20000", "--readme-pictures", str(out / "readme")],
                out / "report")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return out / "report", proc.stdout, proc.stderr


def test_every_section_and_figure_in_both_documents(report):
    from bench.report.document import SECTIONS
    out, _, _ = report
    html = (out / "report.html").read_text()
    md = (out / "report.md").read_text()
    assert "Scene: tiny" in html and "## Scene: tiny" in md
    assert "<h2>Summary</h2>" in html and "## Summary" in md
    for section in SECTIONS:
        assert f"<h3>{section}</h3>" in html
        assert f"### {section}" in md
    for png in ("renders", "shadow_maps", "footprint", "errors", "speed_error", "overlay_texels", "overlay_heatmap",
                "overlay_observer"):
        path = out / "tiny" / f"{png}.png"
        assert path.stat().st_size > 1000, path
        assert f"tiny/{png}.png" in html and f"tiny/{png}.png" in md
    for png in ("comparison", "overlay_observer", "overlay_texels"):
        assert (out.parent / "readme" / f"{png}.png").stat().st_size > 1000
    assert "figure failed" not in html
    assert "n·l ≥ 0.1" in md                      # the lit-facing threshold is stated
    assert "false light = lit where the truth is dark (blue)" in md


def test_numbers_diagnostics_and_failures(report):
    out, stdout, _ = report
    data = json.loads((out / "report.json").read_text())
    scene = data["scenes"][0]
    assert scene["status"] == "ok" and scene["n_min"] > 0
    ok = [m for m in scene["methods"] if m["status"] == "ok"]
    failed = [m for m in scene["methods"] if m["status"] == "failed"]
    assert {m["method"] for m in ok} == {"uniform", "lispsm"} and all(m["size"] == 128 for m in ok)
    assert {m["method"] for m in failed} == {"uniform", "lispsm"} and all(m["size"] == 20000 for m in failed)
    assert all("16384" in m["reason"] for m in failed)
    for m in ok:
        e = m["errors"]
        assert 0 <= e["error_rate"] <= 1 and e["valid"] > 0
        assert e["false_light"] + e["false_shadow"] == round(e["error_rate"] * e["valid"])
        assert m["footprint_lit"]["p95"] > 0 and 0 <= m["footprint_lit"]["frac_above_1"] <= 1
        assert m["footprint_lit"]["count"] <= m["footprint_all"]["count"]
        assert set(m["anatomy"]) >= {"at_edges", "false_light", "unserved", "grazing", "edge_footprint_p95"}
        assert m["m_min"] > 0 and m["max_over_limit"] > 0
        assert "rate" in m["flicker"]
        d = m["diagnostics"]
        assert 0 <= d["theta_deg"] <= 90 and 0 <= d["gamma_deg"] <= 180
        assert isinstance(m["explanation"], list)
        t = m["timing"]
        assert t["repeats"] == 3 and t["min_ms"] <= t["median_ms"] <= t["max_ms"]
        assert t["wall_min_ms"] <= t["wall_median_ms"] <= t["wall_max_ms"] and t["median_ms"] > 0
        assert {"warp", "depth_pass", "shading", "readback"} <= set(t["stages_ms"])
        assert all(v >= 0 for v in t["stages_ms"].values()) and t["first_ms"] > 0
    lispsm = next(m for m in ok if m["method"] == "lispsm")
    assert lispsm["diagnostics"]["n_opt"] is not None
    peers = {p["method"]: p for p in scene["peers"]}
    assert set(peers) == {"eevee", "cycles"}
    for p in peers.values():
        assert p["status"] == "ok", p.get("reason")
        assert p["timing"]["repeats"] == 2 and p["timing"]["min_ms"] <= p["timing"]["median_ms"]
    assert peers["eevee"]["size"] == 128 and "resolution scale" in peers["eevee"]["settings"]
    # Cycles with one delta light and no bounces is exact: it agrees with the ray-cast truth
    assert peers["cycles"]["errors"]["error_rate"] < 0.01
    html = (out / "report.html").read_text()
    assert "16384" in html
    assert "(2/" in stdout and "left)" in stdout              # step k of N, time left
    assert len(scene["overlay_files"]) == 3 and all("overlay" in f for f in scene["overlay_files"])


def test_no_egl_noise_on_the_terminal(report):
    _, stdout, stderr = report
    assert "EGL Error" not in stdout + stderr
    assert "Read blend" not in stdout + stderr
    assert "Push constants" not in stdout + stderr   # the overlay shader's maps ride in a uniform block


def test_the_lambda_guard_is_a_note_not_a_fallback():
    """The λ guard raising λ keeps the method's own construction: the report lists
    it as a note, without the ⚠ that marks a method that fell back."""
    from addon.ui.live import fallbacks_and_notes
    from addon.warp.diagnostics import Diagnostics
    from bench.report.document import _label, _remarks, _warnings
    d = Diagnostics("lispsm", fallbacks=[("split0:main: λ guard", "λ raised from 0.46 to 0.89: below it ..."),
                                         ("main: uniform", "B has no extent along the view")])
    fallbacks, notes = fallbacks_and_notes(d)
    assert fallbacks == [("main: uniform", "B has no extent along the view")]
    assert notes == [("split0:main: λ guard", "λ raised from 0.46 to 0.89: below it ...")]
    rec = {"method": "lispsm", "size": 64, "status": "ok", "maps": [{"role": "main", "size": [64, 64]}],
           "texels": 4096.0, "fallbacks": [], "notes": [list(n) for n in notes], "warnings": [],
           "diagnostics": {"theta_deg": 81.0, "gamma_deg": 81.0, "n_opt": 59.9, "lam": None}}
    assert _label(rec)[0] == "lispsm" and _warnings({"methods": [rec]}) == []
    assert _label(dict(rec, fallbacks=[list(f) for f in fallbacks]))[0] == "lispsm ⚠"
    assert _remarks(rec).startswith("note split0:main: λ guard: λ raised from 0.46 to 0.89")


@pytest.mark.parametrize("bad", [["--scene", "nosuchscene"], ["--methods", "uniform,nosuchmethod"],
                                 ["--scene", "missing.blend"]])
def test_bad_scene_or_method_is_refused_and_the_last_report_stays(report, bad):
    out, _, _ = report
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*")}
    proc = _run(bad, out, timeout=120)
    assert proc.returncode == 2
    assert "error" in proc.stderr and "unchanged" in proc.stderr
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*")} == before
    assert not list(out.parent.glob(".report.partial-*"))


def test_a_run_that_measures_nothing_or_cannot_write_leaves_the_last_report(report, tmp_path):
    out, _, _ = report
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*")}
    proc = _run(["--methods", "uniform", "--sizes", "20000", "--peers", "none", "--no-overlays"], out, timeout=300)
    assert proc.returncode == 1 and "nothing was measured" in proc.stdout + proc.stderr
    (tmp_path / "a file").write_text("")
    proc = _run(["--methods", "uniform"], tmp_path / "a file" / "report", timeout=120)
    assert proc.returncode == 2 and "--out: cannot write in" in proc.stderr and "Traceback" not in proc.stderr
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*")} == before
    assert not list(out.parent.glob(".report.partial-*"))


@pytest.mark.parametrize("where", ["--out a file", "--out a broken link", "--readme-pictures a file",
                                   "the user's own entries in --out", "one scene name twice"])
def test_a_report_that_could_not_be_put_where_asked_is_refused_before_it_runs(tmp_path, where):
    """``--out`` naming a file ran the whole report (12 minutes in full) and then lost it in a traceback; ``--out`` a
    folder of the user's (beside the .blend given as --scene, say) had the user's folder of the scene's name and
    report.md deleted without a word; two scenes of one file name (``chess`` and ``other/chess.blend``) shared one
    folder of figures, the first scene's section showing the second's pictures. Each is refused by name before
    anything runs, and nothing of the user's changes."""
    user = tmp_path / "project"
    (user / "tiny").mkdir(parents=True)
    (user / "tiny" / "notes.txt").write_text("the user's")
    (user / "report.md").write_text("the user's")
    (tmp_path / "a file").write_text("the user's")
    (tmp_path / "a link").symlink_to(tmp_path / "gone")
    args, out, said = {
        "--out a file": ([], tmp_path / "a file", f"--out: {tmp_path / 'a file'} is not a folder: name a folder"),
        "--out a broken link": ([], tmp_path / "a link",
                                f"--out: {tmp_path / 'a link'} is not a folder: name a folder"),
        "--readme-pictures a file": (["--readme-pictures", str(tmp_path / "a file")], tmp_path / "out",
                                     f"--readme-pictures: {tmp_path / 'a file'} is not a folder: name a folder"),
        "the user's own entries in --out": ([], user, f"--out: {user} holds 'report.md', 'tiny', which this report "
                                                      f"would replace and the last report there did not write"),
        "one scene name twice": (["--scene", "tiny,tiny"], tmp_path / "out", "--scene: 'tiny' given twice"),
    }[where]
    before = {p: p.read_text() for p in tmp_path.rglob("*") if p.is_file()}
    proc = _run(["--methods", "uniform", "--sizes", "64", "--peers", "none", "--no-overlays"] + args, out,
                timeout=300)
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert f"error: {said}" in proc.stderr and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    assert "nothing was run; the last report is unchanged" in proc.stderr
    assert {p: p.read_text() for p in tmp_path.rglob("*") if p.is_file()} == before
    assert (tmp_path / "a link").is_symlink()


@pytest.mark.parametrize("args, said", [
    (["--peers", "eevee", "--eevee-samples", "-1"], "--eevee-samples: -1 is not at least 1"),
    (["--peers", "eevee", "--eevee-sizes", "0"], "--eevee-sizes: give positive map sizes in texels per side"),
    (["--peer-repeats", "0"], "--peer-repeats: 0 is not at least 1"),
    (["--methods", "uniform,lispsm,uniform"], "--methods: 'uniform' given twice: each is measured once"),
    (["--sizes", "64,128,64"], "--sizes: '64' given twice: each is measured once"),
    (["--peers", "cycles,cycles"], "--peers: 'cycles' given twice: each is measured once"),
    (["--peers", ""], "--peers: unknown (none given); choose from eevee, cycles or none"),
    (["--resolution", "3x2"], "--resolution: 3x2 is outside 4..8192 pixels per side")])
def test_options_the_report_would_change_or_repeat_are_refused_by_name(tmp_path, args, said):
    """``--eevee-samples -1`` (or 0) rendered EEVEE at 1 sample and the report said "EEVEE -1 spp";
    ``--eevee-sizes 0`` rendered it unmatched (each tile map up to 8192²) and said "at map size(s) 0";
    ``--peer-repeats 0`` was refused as "--frames and --repeats must be at least 1", naming neither; a method, size or
    peer given twice was measured twice and listed twice in every table, with two timings for one point;
    ``--peers ''`` (an empty shell variable) ran no peer without a word; ``--resolution 3x2`` was rendered at 4x4 by
    Blender, and every method failed on "ValueError: operands could not be broadcast together". Each is refused by
    name before anything runs."""
    base = {"--methods": "uniform", "--sizes": "64", "--peers": "none"}
    for option in args[::2]:
        base.pop(option, None)
    proc = _run([v for kv in base.items() for v in kv] + ["--no-overlays"] + args, tmp_path / "out", timeout=300)
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert f"error: {said}" in proc.stderr and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("first, more, said", [
    ("missing.json", [], "argument first: cannot read {tmp}/missing.json: No such file or directory"),
    ("not json.txt", [], "argument first: {tmp}/not json.txt is not a report.json of python -m bench.report"),
    ("a list.json", [], "argument first: {tmp}/a list.json is not a report.json of python -m bench.report"),
    ("empty folder", [], "argument first: cannot read {tmp}/empty folder/report.json: No such file or directory"),
    ("report/report.json", ["--limit", "0.5"], "argument --limit: 0.5: give a ratio of 1 or more, e.g. 1.3"),
    ("report/report.json", ["--limit", "nan"], "argument --limit: nan: give a ratio of 1 or more, e.g. 1.3"),
    ("report/report.json", ["--limit", "fast"], "argument --limit: fast: give a ratio of 1 or more, e.g. 1.3")])
def test_comparing_timings_of_what_is_not_a_report_says_which_argument_and_why(tmp_path, capsys, first, more, said):
    """``python -m bench.report.timing A B`` given a missing file, a folder, or a file that is not a report.json
    stopped in a traceback; a --limit below 1 failed every comparison (no two medians differ by less than 1x), and NaN
    did so saying '0 above nanx'. Now argparse names the argument, and a report's folder may be given for its
    report.json."""
    from bench.report.timing import main
    (tmp_path / "not json.txt").write_bytes(b"\xff\xfe not json")
    (tmp_path / "a list.json").write_text("[]")
    (tmp_path / "empty folder").mkdir()
    (tmp_path / "report").mkdir()
    (tmp_path / "report" / "report.json").write_text(json.dumps({"scenes": [{"name": "s", "methods": [
        {"method": "uniform", "size": 64, "status": "ok", "timing": {"median_ms": 2.0, "wall_median_ms": 3.0}}]}]}))
    with pytest.raises(SystemExit) as stopped:
        main([str(tmp_path / first), str(tmp_path / "report" / "report.json")] + more)
    err = capsys.readouterr().err
    assert stopped.value.code == 2 and "Traceback" not in err
    assert f"python -m bench.report.timing: error: {said.format(tmp=tmp_path)}" in err, err
    assert main([str(tmp_path / "report"), str(tmp_path / "report" / "report.json")]) == 0
    assert "1 points; worst ratio 1.00x; 0 above 1.3x" in capsys.readouterr().out


def test_a_figure_of_a_scene_whose_file_name_has_a_space_or_a_hash_is_linked_in_both_documents():
    """``--scene "my shot #2.blend"`` names the scene's folder of figures so: in report.md the space ended the link
    (``![Renders](my shot #2/renders.png)`` shows as text) and in both documents the '#' cut the path. The link is
    the path URL-encoded, which reads back as the file's path."""
    from urllib.parse import unquote
    from bench.report.document import Block, to_html, to_markdown
    bs = [Block("h1", "Lixel"), Block("img", "my shot #2/renders.png", "Renders")]
    assert "![Renders](my%20shot%20%232/renders.png)" in to_markdown(bs)
    assert "<img src='my%20shot%20%232/renders.png' alt='Renders'>" in to_html(bs)
    assert unquote("my%20shot%20%232/renders.png") == "my shot #2/renders.png"


def test_publish_replaces_only_the_reports_own_entries(tmp_path):
    from bench.report.__main__ import MANIFEST, publish
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("the user's")
    (out / "old_scene").mkdir()
    (out / "report.html").write_text("old")
    (out / MANIFEST).write_text("old_scene\nreport.html\n")
    partial = tmp_path / "partial"
    (partial / "new_scene").mkdir(parents=True)
    (partial / "report.html").write_text("new")
    publish(partial, out)
    assert (out / "notes.txt").read_text() == "the user's"
    assert not (out / "old_scene").exists() and (out / "new_scene").is_dir()
    assert (out / "report.html").read_text() == "new" and not partial.exists()


def test_noise_filter_keeps_real_messages():
    from bench.report.progress import is_noise
    assert is_noise("EGL Error (0x3009): EGL_BAD_MATCH: Arguments are inconsistent")
    assert is_noise('00:00.789  blend            | Read blend: "/x/forest.blend"')
    assert is_noise("Fra:1 Mem:42.12M (Peak 42.12M) | Time:00:10.20 | Rendering 1 / 1 samples")
    assert not is_noise("Error: Not freed memory blocks: 3")
    assert not is_noise("Traceback (most recent call last):")


def test_the_header_says_which_scenes_had_fewer_frames_than_asked():
    """``--frames 100000`` said "100000 frame(s) of camera animation" over a report whose scene animates 8: each
    scene renders its own frames up to the number asked, and the header names the scenes that had fewer."""
    from bench.report.document import _header
    result = {"blender": "5.0.1", "seconds": 3, "options": {
        "quick": False, "scenes": ["chess", "forest"], "methods": ["uniform"], "sizes": [16], "resolution": [32, 32],
        "frames": 100000, "repeats": 1, "peer_repeats": 3, "cycles_samples": 1, "eevee_samples": 1},
        "scenes": [{"name": "chess", "frames": list(range(1, 9))}, {"name": "forest", "frames": list(range(1, 5))}]}
    assert "100000 frame(s) of camera animation (fewer where a scene's ends first: chess 8, forest 4);" in \
        _header(result)[0]
    result["options"]["frames"] = 4
    assert "; 4 frame(s) of camera animation; " in _header(result)[0]


def test_timing_summary_and_agreement():
    from bench.report.timing import agreement, summarise
    t = summarise([(0.010, 0.005), (0.030, 0.004), (0.020, 0.006)], [{"a": 0.001}, {"a": 0.003}, {"a": 0.002}])
    assert (t.wall_median_ms, t.wall_min_ms, t.wall_max_ms, t.repeats) == (20.0, 10.0, 30.0, 3)
    assert (t.median_ms, t.min_ms, t.max_ms) == pytest.approx((5.0, 4.0, 6.0))   # the CPU time is the timed point
    assert t.stages_ms == {"a": 2.0}
    rep = lambda ms: {"scenes": [{"name": "s", "methods": [{"method": "m", "size": 8, "status": "ok",  # noqa: E731
                                                            "timing": {"median_ms": ms}}], "peers": []}]}
    key, worst = agreement(rep(10.0), rep(12.5)).worst
    assert key == ("s", "m", 8) and worst == pytest.approx(1.25)


def test_pareto_front_keeps_only_undominated_points():
    from bench.report.figures import pareto_front
    pts = [(10, 5.0), (20, 1.0), (15, 6.0), (5, 9.0), (30, 1.0), (25, 0.5)]
    assert sorted(pareto_front(pts)) == [0, 1, 3, 5]


def test_explanation_names_lost_shadows_when_footprint_and_error_disagree():
    from bench.report.analysis import explain
    ref = {"footprint_lit": {"p95": 2.0}, "errors": {"error_rate": 0.01, "false_light": 200, "false_shadow": 100},
           "anatomy": {"edge_footprint_p95": 2.0}}
    anatomy = {"unserved": 0.0, "interior_false_light": 0.8, "interior_false_shadow": 0.05, "grazing": 0.0,
               "at_edges": 0.15, "false_light": 0.85, "edge_false_light": 0.5, "edge_footprint_p95": 0.6,
               "errors": 900}
    rec = {"footprint_lit": {"p95": 0.5}, "errors": {"error_rate": 0.03, "false_light": 765, "false_shadow": 135},
           "fallbacks": [], "anatomy": anatomy}
    text = explain(rec, ref, "uniform")
    assert "predicts a smaller error (about 75 wrong pixels against uniform's 300); rendered 3.00× (900)" in text
    assert "whole shadows lost" in text
    # a smaller footprint and a smaller error agree
    assert explain(dict(rec, errors={"error_rate": 0.004, "false_light": 90, "false_shadow": 30}), ref, "u") is None
    # a smaller footprint and the same error disagree: warping bought nothing
    same = dict(rec, errors={"error_rate": 0.0102, "false_light": 200, "false_shadow": 106})
    assert "predicts a smaller error (about 75 wrong pixels against uniform's 300); rendered 1.02× (306)" in \
        explain(same, ref, "uniform")
    # too few wrong pixels to tell the prediction from the render: no verdict
    few_ref = dict(ref, errors={"error_rate": 0.0002, "false_light": 15, "false_shadow": 6})
    few = dict(rec, errors={"error_rate": 0.0002, "false_light": 6, "false_shadow": 2})
    assert explain(few, few_ref, "uniform") is None
