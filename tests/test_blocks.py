"""Generated blocks (ikbench.render.blocks): README.md's and docs/'s measured figures are
rendered from committed results files, and each block equals a fresh render."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

from ikbench.core.errors import InputError
from ikbench.render.blocks import blocks, check_files, documents, render_text
from tests.conftest import REPO


def test_every_generated_block_equals_a_fresh_render():
    stale = check_files(documents(REPO), REPO)
    assert not stale, "run `ikbench reproduce --docs`:\n" + "\n".join(stale)


def test_no_inline_block_starts_a_line():
    """mkdocs reads a line that starts with ``<!--`` as raw HTML, which ends the paragraph: an
    inline block (value, range, fraction, list, provenance, paired) stands after text on its
    line."""
    inline = re.compile(r"^<!-- generated: (value|range|fraction|list|provenance|paired) ",
                        re.M)
    starts = [f"{page.relative_to(REPO)}:{text[:m.start()].count(chr(10)) + 1}"
              for page in documents(REPO)
              for text in [page.read_text(encoding="utf-8")] for m in inline.finditer(text)]
    assert not starts, starts


def test_readme_has_its_leaderboard_as_a_block():
    kinds = [(b.renderer, b.source) for b in blocks(REPO / "README.md")]
    assert ("compare-table", "results/compare/leaderboard.csv") in kinds


@pytest.fixture
def results(tmp_path):
    folder = tmp_path / "results" / "study"
    folder.mkdir(parents=True)
    (folder / "table.csv").write_text("method,time_s,ok\nfast,0.00123,True\nslow,2.5,False\n")
    (folder / "run.json").write_text(json.dumps({
        "git_commit": "0123456789abcdef0123", "git_clean": True, "cpu": "Test CPU",
        "cpu_count": 2, "load_average": [1.5, 1.0, 0.5], "created_utc": "2026-11-25T10:00"}))
    return tmp_path


def test_a_table_block_renders_the_rows_and_the_provenance(results):
    text = ("before\n<!-- generated: table results/study/table.csv where=ok:True "
            "columns='method,time_s:time [s]' -->\nold\n<!-- /generated -->\nafter\n")
    out = render_text(text, results)
    assert "| method | time [s] |" in out and "| fast | 0.00123 |" in out
    assert "slow" not in out
    assert ("*Measured at commit 0123456789ab, clean tree on Test CPU (2 logical CPUs), load "
            "1.5, 1, 0.5, 2026-11-25; from `results/study/table.csv`.*") in out
    assert out.startswith("before\n") and out.endswith("after\n")
    assert render_text(out, results) == out           # rendering again changes nothing


def test_a_value_block_stands_inline(results):
    text = ("fast takes <!-- generated: value results/study/table.csv where=method:fast "
            "column=time_s scale=1000 unit=ms format=.2f --><!-- /generated --> per call")
    out = render_text(text, results)
    assert "-->1.23 ms<!--" in out


def test_value_aggregates_ranges_fractions_and_json_keys(results):
    folder = results / "results" / "study"
    (folder / "summary.json").write_text(json.dumps({"this_run": {"rate_per_s": 1234.5}}))
    text = ("<!-- generated: value results/study/table.csv column=time_s agg=max unit=s -->"
            "<!-- /generated --> | <!-- generated: range results/study/table.csv column=time_s "
            "scale=1000 format=.0f unit=ms --><!-- /generated --> | <!-- generated: fraction "
            "results/study/table.csv column=ok --><!-- /generated --> | <!-- generated: value "
            "results/study/summary.json key=this_run.rate_per_s format=,.0f --><!-- /generated -->")
    out = render_text(text, results)
    assert "-->2.5 s<!--" in out and "-->1-2500 ms<!--" in out and "-->1/2<!--" in out
    assert "-->1,234<!--" in out or "-->1,235<!--" in out


def test_an_ik_table_of_a_repeated_rule_gives_the_spread(results):
    folder = results / "results" / "ik" / "panda"
    folder.mkdir(parents=True)
    (folder / "summary.csv").write_text(
        "attempts_rule,method,targets,success_pct,time_median_ms,batched_per_s,batched_threads,"
        "runs,success_pct_min,success_pct_max,time_median_ms_min,time_median_ms_max\n"
        "auto,trac-ik,10,99.85,0.212,,,3,99.8,99.9,0.205,0.22\n"
        "8,trac-ik,10,99,0.3,,,1,99,99,0.3,0.3\n")
    (folder / "run.json").write_text((results / "results/study/run.json").read_text())
    text = "<!-- generated: ik-table results/ik robots=panda --><!-- /generated -->"
    assert "| trac-ik | 99.85 % (99.80-99.90), 0.212 (0.205-0.22) ms |" in render_text(text,
                                                                                      results)
    text = "<!-- generated: ik-table results/ik robots=panda rule=8 --><!-- /generated -->"
    assert "| trac-ik | 99.00 %, 0.3 ms |" in render_text(text, results)


def test_an_ik_table_puts_the_robots_side_by_side(results):
    head = ("attempts_rule,method,targets,success_pct,time_median_ms,batched_per_s,"
            "batched_threads\n")
    for robot, rows in (("panda", "auto,ours-lm,10,100,0.03,25000,2\nauto,trac-ik,10,98.5,0.4,,\n"
                                  "1,ours-lm,10,50,0.07,,\nauto,placo,10,0,,,\n"),
                        ("ur5", "auto,ours-lm,10,99.9,0.02,40000,2\n")):
        folder = results / "results" / "ik" / robot
        folder.mkdir(parents=True)
        (folder / "summary.csv").write_text(head + rows)
        (folder / "run.json").write_text((results / "results/study/run.json").read_text())
    text = "<!-- generated: ik-table results/ik robots=panda,ur5 --><!-- /generated -->"
    out = render_text(text, results)
    assert "| method | panda: success, per-call median | ur5: success, per-call median |" in out
    assert "| ours-lm | 100.00 %, 0.03 ms | 99.90 %, 0.02 ms |" in out
    assert "| trac-ik | 98.50 %, 0.4 ms | not run |" in out
    assert "| placo | 0.00 %, no call timed (failed rows) | not run |" in out
    assert "50.00 %" not in out                      # the other attempts rule's table
    assert "ours-lm 25,000 IK/s on panda (2 threads); ours-lm 40,000 IK/s on ur5" in out
    assert out.count("*Measured at commit") == 2
    with pytest.raises(InputError, match="no row with attempts_rule '3'"):
        render_text(text.replace("robots=panda,ur5", "rule=3"), results)


def test_a_retyped_figure_is_found_stale(results, tmp_path):
    page = tmp_path / "page.md"
    page.write_text("<!-- generated: value results/study/table.csv where=method:slow "
                    "column=time_s unit=s -->2.4 s<!-- /generated -->\n")
    assert len(check_files([page], tmp_path)) == 1
    page.write_text(render_text(page.read_text(), tmp_path))
    assert check_files([page], tmp_path) == []


@pytest.mark.parametrize("spec, message", [
    ("table", "needs 'RENDERER SOURCE'"),
    ("nonsense results/study/table.csv", "renderer 'nonsense' is unknown"),
    ("value results/study/table.csv column=time_s", "leaves 2 rows, not one"),
    ("value results/study/table.csv column=nope where=method:fast", "column='nope'"),
    ("table results/missing.csv", "does not exist"),
    ("table results/study/table.csv where=nope:1", "no column 'nope'"),
    ("value results/study/table.csv column=time_s agg=mode", "agg='mode' is unknown"),
    ("range results/study/table.csv column=method", "holds text, not numbers"),
    ("fraction results/study/table.csv column=ok where=method:none", "leaves no row"),
    ("value results/study/run.json key=cpu", "is 'Test CPU', not a number"),
    ("value results/study/run.json key=gpu.name", "no 'gpu' there"),
])
def test_a_bad_block_is_one_clear_error(results, spec, message):
    with pytest.raises(InputError, match=message):
        render_text(f"<!-- generated: {spec} --><!-- /generated -->", results)


def test_reproduce_docs_and_plan_through_the_cli():
    docs = subprocess.run([sys.executable, "-m", "ikbench.cli", "reproduce", "--docs"],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert docs.returncode == 0 and docs.stdout.startswith("rendered: nothing changed"), \
        docs.stdout + docs.stderr
    plan = subprocess.run([sys.executable, "-m", "ikbench.cli", "reproduce", "--plan"],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert plan.returncode == 0, plan.stderr
    assert "ikbench reproduce --output results" in plan.stderr
    assert "ikbench compare --methods" in plan.stderr
    bad = subprocess.run([sys.executable, "-m", "ikbench.cli", "reproduce", "--all", "--only",
                          "nope"], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "--only: nope is not a study" in bad.stderr


# ----- no measured figure outside a generated block or a published label ---------------------
NUMBER = r"\d+(?:[.,]\d+)*(?:e[-+]?\d+)?"
UNIT = (r"(?:ns|us|µs|μs|ms|s|sec|seconds?|min|minutes?|h|hours?|mm|cm|m|km|millimetres?|deg|"
        r"degrees?|rad|ulps?|B|kB|KB|MB|GB|TB|Hz|it/s|traj/s|trajectories/s|IK/s|targets/s|"
        r"mm/s|deg/s|rad/s|m/s|deg\^2|mm\^2|percent)")
#: A measured figure's shape: a number, or a range or pair of numbers, with a unit of time,
#: length, angle, size, rate, share (%) or ratio (x). Extends the pattern tests/test_results.py
#: used for README alone.
FIGURE = re.compile(rf"(?<![\w.^/=])(?<![\w.]-){NUMBER}(?:\s*(?:-|to|/|vs)\s*{NUMBER})*"
                    rf"(?:\s*{UNIT}(?![\w/^])|\s*%|°|x(?!\w))")
#: Specification values that prose keeps: each phrase (as written, any run of white space
#: matching any other) holds a figure that is a setting, a tolerance, a limit or a definition,
#: not a measurement; the value says why.
SPECIFICATION = {
    "judged success [%] (1 mm, 0.5 deg)": "ikbench ik's default tolerances (--tolerance-mm, "
    "--tolerance-deg), docs/learned.md's column table",
    "fingertip x <= -250 mm, z >= 0 mm, at least 100 mm below the start point, finger within "
    "20 deg of the line direction": "NICO's [batch] workspace filter (urdf/nico_right_arm.toml)",
    "mean line distance below 1 mm": "ikbench batch's line tolerance",
    "end point error below 0.5 mm": "ikbench batch's end point tolerance",
    "and 98 % of the contract's speed limit (NICO at T = 2 s, n = 50: 10.8 motor deg per "
    "segment); for pose paths, 95 % of CppFlow's 7 deg / 20 mm": "ours-exact's step limits "
    "(CONTRACT_STEP_SHARE, PATH_STEP_SHARE) on the contract's speed limit and CppFlow's joint "
    "step criteria (ikbench/core/validity.py)",
    "constraints within (1e-6 mm and deg)": "ours-exact's default --exact-feasibility-tolerance",
    "letters 300 mm high": "the default --size of ikbench letters and sweep (the paper's letter "
    "setting)",
    ">= 200 000 trajectories/s at a batch of 100 000 in float32, <= 10 ms for the paper's "
    "seven": "the GPU issue's aims for the torch backend (targets, not measurements)",
    # docs/shapes.md
    "every pen-down point within 10 mm of the target curve (a thirtieth of the letters' "
    "default 300 mm height) and at least 95 % of the curve's strokes within 10 mm of the "
    "fingertip's path": "the drawn-shape judge (DRAWN_TOLERANCE_MM, DRAWN_COVERAGE_MIN_PCT, "
    "ikbench/core/metrics.py)",
    "(sampled every 1 mm) within 10 mm of": "the drawn-shape judge's sampling "
    "(COVERAGE_SPACING_MM, ikbench/core/shapes.py) and tolerance",
    # docs/recommend.md
    "a margin of a tenth of it, at least 10 s": "recommend's stated margin past --minutes",
    "a paired-bootstrap 95 % interval (2000 resamples, seeded)": "recommend's paired "
    "comparison (ikbench.studies.recommend.paired)",
    "it is never ranked as 0 %": "what a cannot-run row is not (no measurement)",
    # docs/baselines.md
    "the touch pose's own over the last 20 %": "the tracking scheme's landing share "
    "(LANDING_FRACTION, ikbench/schemes/track.py)",
    "a warm start on a limit is nudged 1e-3 rad inside": "the ikpy adapter's margin inside "
    "the bounds (INSIDE, baselines/ikpy_ik.py)",
    "allows |e| up to 1.4e-3 m": "sqrt(2 x 1e-6): the bound rtb's default tol on "
    "E = 1/2 |e|^2 implies, not a measurement",
    # docs/collisions.md
    "its surface 3 mm beyond the deepest touch": "the touchscreen's allowance "
    "(urdf/nico_right_arm.touchscreen.json)",
    "agree with coal to 0.1 mm": "tests/test_capsules.py's tolerance",
    "Position error < 0.1 mm, rotation error < 0.1 deg, joint steps < 7 deg (20 mm prismatic)":
    "CppFlow's validity thresholds (ikbench.core.validity)",
    "within 0.5 mm / 0.5 deg that collide": "the path search's ANCHOR_TOLERANCE",
    "within 1 mm / 1 deg of its goal": "the path search's STITCH_REACHED",
    "beyond 6.5 deg (18.6 mm prismatic)": "the path search's STITCH_MAX_STEP (prismatic: "
    "times CppFlow's 20 mm / 7 deg)",
    "jumps by more than 14 deg": "the path search's RETRACK_STEP, twice CppFlow's 7 deg step",
    "closer than 40 mm": "the collision push's ACTIVATION_MM (ikbench/methods/ours_lm)",
    "above CppFlow's 7 deg (below 60 deg)": "the path search's repair range: CppFlow's step "
    "limit up to REPAIRABLE x 7 deg (ikbench/methods/ours_lm/path_search.py)",
    "steps of 1.5 deg along the null vector": "the self-motion sweep's SWEEP_STEP",
    "every step below 6.93 deg": "REPAIR_STEP x CppFlow's 7 deg",
    "A step above 7 deg that is left": "CppFlow's step limit (ikbench.core.validity)",
    "the least excess over 7 deg": "CppFlow's step limit (ikbench.core.validity)",
    "every path steps more than 7 deg": "CppFlow's step limit (ikbench.core.validity)",
    "Where the stitch steps above 7 deg": "CppFlow's step limit (ikbench.core.validity)",
    "moved 1, 2 and 3 cm along each of +-x, +-y, +-z": "the moved-obstacles check's offsets "
    "(benchmarks/moved_obstacles.py)",
    "with its boxes 3 cm higher": "one of the moved-obstacles check's offsets",
    "their obstacles moved 1-3 cm in six directions": "the moved-obstacles check's offsets",
    # docs/hardware.md
    "2048 = 0 deg": "the MX goal position register's centre (Dynamixel MX control table)",
    "+180 deg (raw 4096) is sent as 4095 (179.91 deg)": "the MX encoder's top step, "
    "4095 x 360/4096 deg",
    "one unit is 0.114 rpm = 0.684 deg/s": "the MX moving speed register's unit (Dynamixel "
    "MX control table; SPEED_UNIT_DEG_S)",
    "at the hold speed, 10 deg/s": "the executor's HOLD_SPEED_DEG_S (ikbench/hw/executor.py)",
    "within 0.2 deg of the last pose, for at most 0.5 s": "the executor's settle check "
    "(SETTLE_TOLERANCE_DEG, SETTLE_S)",
    "adapters with an FTDI chip wait up to 16 ms": "the FTDI driver's default latency timer, "
    "a device setting",
    "2 x 16 + 2 = 34 ms": "dynamixel-sdk's status timeout from its LATENCY_TIMER = 16",
    # docs/commands.md
    "up to 10,000 Hz, 0 for one point per pose": "export --rate's accepted values "
    "(MAX_RATE_HZ, ikbench/viewer/export.py)",
    "300 mm, c0=1, c1=50, c6=1, 2000 Adam iterations": "the paper's letter setting, the "
    "defaults of ikbench letters",
    # docs/contributing.md
    "at least 99 % of the public functions are annotated": "tests/test_annotations.py's "
    "REQUIRED threshold",
    # docs/comparison.md, docs/timing.md
    "40 ms at T = 2 s": "T/n at the paper's T and n = 50 (a definition)",
    "T = 2 s": "the paper's trajectory duration, the default --duration (Contract.duration_s)",
    "5 mm (the largest distance)": "the contract's default line tolerance "
    "(ikbench/core/contract.py)",
    "judged on the last 80 % of the steps (from step ceil(0.2 n)) | 15 deg mean": "the "
    "contract's judged part (pointing_judged_from = 0.2) and default pointing tolerance",
    "a servo whose resolution is 0.088 deg": "the MX encoder's step, 360/4096 deg (Dynamixel "
    "MX control table)",
    "each touch pose within 45 deg of it on every joint (on its IK branch), at least 100 mm "
    "lower, above the table, the hand within 30 deg of the line": "urdf/generate_panda_lines.py's "
    "REACH_DEG and the Panda's [batch] filter (urdf/panda.toml)",
    "2.175 rad/s (joints 1-4), 2.61 rad/s (5-7)": "the Panda URDF's <limit velocity>",
    "still gets 0.1 % of the mean": "the spline parameter's floor (MIN_PARAMETER_FRACTION, "
    "ikbench/core/timed_path.py)",
    "Segments must be at least 5 ms": "the executor's shortest segment (MIN_SEGMENT_S, "
    "ikbench/hw/plan.py)",
    "default 250 Hz": "export --rate's default (DEFAULT_RATE_HZ, ikbench/viewer/export.py)",
    "270 deg/s (the slowest MX no-load speed at 12 V)": "NICO's motor table's max_speed_deg_s "
    "(urdf/nico_right_arm.dynamixel.json)",
    "velocity limit / 0.5 s": "the acceleration assumed without a stated one "
    "(DEFAULT_ACCELERATION_TIME_S, ikbench/core/timing_limits.py)",
    # docs/cartesian.md
    "end frame = flange (0.107 m) turned -45 deg about z": "the Panda URDF's flange offset "
    "and hand mounting (urdf/panda.urdf, from franka_description's joint origins)",
    # docs/results-at-a-glance.md, docs/viewer.md
    "the fingertip within 5 mm of the line at every step, pointing along the line within 15 deg "
    "on average over the last 80 % of the steps": "the contract's default tolerances and "
    "judged part (DEFAULT_TOLERANCES, DEFAULT_POINTING_FROM, ikbench/core/contract.py)",
    "finds every position within 1e-9 rad": "tests/test_export.py's tolerance on the exported "
    "URDF angles",
    "the CSV's motor degrees come back to 1e-9 deg": "tests/test_export.py's round-trip "
    "tolerance",
    "the drawn end frame against ikbench's FK to 1e-9 m": "tests/test_viewer.py's tolerance "
    "(yourdfpy against Pinocchio)",
    "3 deg of pointing weigh as much as 1 mm of position": "the designer's IK weighting "
    "(POINTING_TOLERANCE_DEG, ikbench/viewer/design/reach.py)",
    "its height (20 to 1000 mm)": "the letter heights the designer accepts (SIZE_RANGE_MM, "
    "ikbench/viewer/design/kinds.py)",
    "20 times along a circle of radius 20 mm per round": "benchmarks/designer_latency.py's "
    "--moves default and RADIUS_MM",
    "a median of at most 50 ms with ours-lm and 100 ms with ours-exact": "the designer "
    "issue's aims (issue 35; targets, not measurements)",
    "the first frame is held 0.5 s longer and the last (the touch) 1 s longer": "the "
    "animation's HOLD_FIRST_S and HOLD_LAST_S (ikbench/render/animation.py)",
    "so 4.35 s is": "a worked example of the export's whole-nanosecond times (arithmetic)",
    # docs/robots.md: the URDF limits
    "larger than 20 MB, or with more than 5,000": "the URDF size limits (MAX_URDF_BYTES, "
    "MAX_LINKS, ikbench/core/urdf_model.py)",
    "within +-1e4 rad (revolute) or +-1e3 m (prismatic)": "the joint-limit bounds "
    "(MAX_LIMIT_RAD, MAX_LIMIT_M, ikbench/core/urdf_model.py)",
    "within 30 deg of": "robot init's first reach (REACHES_DEG, ikbench/core/robot_init.py)",
    "(15 deg, the contract's pointing tolerance)": "POINTING_DEG (ikbench/core/robot_init.py)",
    "(45 deg) of it at the start pose": "START_POINTING_DEG (ikbench/core/robot_init.py)",
    # docs/experiment.md, docs/experiment-browser.md: the authors' design and the defaults
    "stops at 60 % or 80 % of its path": "the authors' design (Lucny et al., ICSR 2025)",
    "2400 x 1350 px, 46.7 x 26.7 cm": "the authors' screen (andylucny/nico2 "
    "experiment/display.txt; urdf/nico_right_arm.experiment.json)",
    "the whole path (default 2 s, the authors')": "design --duration's default",
    "how long the head moves before the arm (default 0.5 s)": "design --gaze-lead's default",
    "within 2 mm of the stop point and the head within 0.2 deg of its":
        "tests/test_experiment.py's tolerances on the emulator",
    "The touch scatters 3 mm around the answered target": "the observers' touch_sd_mm default",
    "(median 0.9 s). An answer slower than the 2 s window": "the observers' reaction-time "
    "default and the authors' response window",
    "Wilson 95 % intervals": "the intervals' coverage",
    "paired bootstrap 95 % interval over targets": "the bare-calls study's intervals "
    "(benchmarks/ours_lm_vs_bare.py)",
    "simulation gaze 3 deg, pointing and position 6 deg": "the worked example's simulation "
    "(the observers' defaults)",
    "pointing read to 6 degrees": "the observers' default pointing noise",
    "(at least 0.3 s, as the bus back-end plays it)": "the head turn's shortest time "
    "(ikbench/experiment/play.py)",
    "(design.json, 2 s)": "the authors' response window",
    "stop frames at 60 % for target 3": "the screenshots' preview parameters",
    "the arm has gone 60 % of its path": "the screenshots' preview parameters",
    "fill 90 % of the view": "the online page's framing (ikbench/experiment/scene.py)",
    "GP at 60 % toward": "the frame sheet's stimulus",
    "conditions G, P, GP, I at 60 %.": "the screenshots' design",
}
#: Text that is not prose: generated blocks, fenced code, inline code, comments, link targets.
NOT_PROSE = [re.compile(r"```.*?```", re.S), re.compile(r"<!--.*?-->", re.S),
             re.compile(r"`[^`\n]*`"), re.compile(r"\]\([^)\s]*\)")]


def unlabelled_figures(text: str) -> list[tuple[int, str, str]]:
    """(line number, figure, line) of each figure of ``text`` (a Markdown page) outside
    generated blocks and code, on a line that does not say "published" (nor stands in a
    section whose heading does), and not within a phrase of :data:`SPECIFICATION`."""
    from ikbench.render.blocks import BLOCK

    def blank(match: re.Match) -> str:
        return re.sub(r"[^\n]", " ", match[0])

    text = BLOCK.sub(blank, text)
    for pattern in NOT_PROSE:
        text = pattern.sub(blank, text)
    for phrase in SPECIFICATION:
        text = re.sub(r"\s+".join(map(re.escape, phrase.split())), blank, text)
    found, published_level = [], 0
    for number, line in enumerate(text.split("\n"), 1):
        heading = re.match(r"(#+)\s", line)
        if heading:
            level = len(heading[1])
            if published_level and level <= published_level:
                published_level = 0
            if "published" in line.lower():
                published_level = level
        if published_level or "published" in line.lower():
            continue
        found += [(number, m[0], line.strip()) for m in FIGURE.finditer(line)]
    return found


#: Pages (file stems) whose figures are not yet all generated or labelled: empty since issue 36's
#: docs audit, and no page may join it (the ratchet test checks each one still fails the scan).
NOT_YET_AUDITED: frozenset[str] = frozenset()


def test_the_audit_ratchet_only_shrinks():
    """Every page of the ratchet exists and still fails the scan (else take it off)."""
    pages = {p.stem: p for p in documents(REPO)}
    for name in NOT_YET_AUDITED:
        assert name in pages, f"{name} is not a page any more: take it off NOT_YET_AUDITED"
        assert unlabelled_figures(pages[name].read_text(encoding="utf-8")), \
            f"{name} passes the scan now: take it off NOT_YET_AUDITED"


@pytest.mark.parametrize("page", [p for p in documents(REPO) if p.stem not in NOT_YET_AUDITED],
                         ids=lambda p: p.relative_to(REPO).as_posix())
def test_no_measured_figure_outside_a_generated_block_or_a_published_label(page):
    """Every measured figure of README.md and docs/ comes from results/ through a generated
    block; a figure of another project is labelled published with its source; prose keeps
    only the specification values of :data:`SPECIFICATION`."""
    found = unlabelled_figures(page.read_text(encoding="utf-8"))
    assert not found, "\n".join(f"{page.name}:{n}: {figure!r} in: {line[:120]}"
                                for n, figure, line in found)


def test_the_figure_scan_finds_what_it_should():
    text = ("takes 0.35 ms and 2.0-2.5 s, 98.65 %, 15x, 1e-6 mm, 218 traj/s, 5.2 GB\n"
            "`--budget-ms 5 ms` <!-- generated: value results/x.csv column=t -->3 ms"
            "<!-- /generated --> and [a](../results/4_mm.md)\n"
            "TRAC-IK's published 0.38 ms\n## Published figures\n| 0.3 ms |\n## Next\n"
            "c0 = 100, n = 50, 7x7 blocks, step 30 of 50, 12 mm\n")
    figures = [figure for _, figure, _ in unlabelled_figures(text)]
    assert figures == ["0.35 ms", "2.0-2.5 s", "98.65 %", "15x", "1e-6 mm", "218 traj/s",
                       "5.2 GB", "12 mm"]


def test_a_paired_block_pairs_by_trajectory_and_calls_a_tie(tmp_path):
    folder = tmp_path / "results" / "cmp"
    folder.mkdir(parents=True)
    rows = ["method,trajectory,legibility,track"]
    a = [0.41, 0.42, 0.43, 0.44, 0.45, 0.40, 0.39]
    b = [0.40, 0.41, 0.42, 0.43, 0.44, 0.41, 0.40]
    rows += [f"x,{i},{v},paper" for i, v in enumerate(a)]
    rows += [f"y,{i},{v},paper" for i, v in reversed(list(enumerate(b)))]  # order is no pairing
    rows += ["y,0,9.9,other"]  # filtered out by where=
    (folder / "results.csv").write_text("\n".join(rows) + "\n")
    spec = "paired results/cmp/results.csv column=legibility a=x b=y where=track:paper"
    out = render_text(f"On seven: <!-- generated: {spec} --><!-- /generated -->", tmp_path)
    assert "x is higher than y on 5 of 7 (sign test p = 0.45;" in out and out.endswith(
        ": a tie<!-- /generated -->")
    worse = render_text(f"<!-- generated: {spec} higher=worse column=track -->"
                        "<!-- /generated -->".replace("column=track", ""), tmp_path)
    assert "a tie" in worse
    pending = render_text(f"<!-- generated: {spec.replace('=legibility', '=later')} pending=1 "
                          "--><!-- /generated -->", tmp_path)
    assert "not measured in `results/cmp/results.csv` yet" in pending
    with pytest.raises(InputError, match="no column 'later'"):
        render_text(f"<!-- generated: {spec.replace('=legibility', '=later')} -->"
                    "<!-- /generated -->", tmp_path)
    with pytest.raises(InputError, match="no row of method 'z'"):
        render_text(f"<!-- generated: {spec.replace('b=y', 'b=z')} --><!-- /generated -->",
                    tmp_path)
