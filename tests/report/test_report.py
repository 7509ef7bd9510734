import contextlib
import json
import re
import shutil
import subprocess

import numpy as np
import pytest

import bedstruct
from bedstruct.cli import main
from bedstruct.report import ReportOptions, build_report, render_html, select_frames, write_report
from bedstruct.report import build as build_mod
from bedstruct.report import _picture
from lattices import cubic_lattice

_REAL_RENDER_3D = _picture.render_3d


def _note_instead_of_3d(frame, **kw):
    return None, "3-D view not drawn (left out in the tests)"


@pytest.fixture(autouse=True)
def _no_3d_render(monkeypatch):
    """The 3-D view takes seconds in a child process: the tests of it render it, the
    others get a note instead."""
    monkeypatch.setattr(_picture, "render_3d", _note_instead_of_3d)


@contextlib.contextmanager
def _only(*keys):
    """Reports built inside (by build_report or the CLI) run only the named sections; the
    input is judged and pictured as always. For tests of one section's numbers."""
    todo = [s for s in build_mod.SECTIONS if s[0] in keys]
    assert [s[0] for s in todo] == [k for k, _, _ in build_mod.SECTIONS if k in keys] and len(todo) == len(keys)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(build_mod, "SECTIONS", todo)
        yield


@pytest.fixture(scope="module")
def bed_dump(tmp_path_factory):
    """A jittered polydisperse slab, written as a LIGGGHTS dump in micrometres."""
    rng = np.random.default_rng(1)
    n = (24, 6, 4)
    g = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1).reshape(-1, 3)
    pos = (g + 0.5) * 50.0 + rng.normal(0, 2.0, g.shape)
    r = rng.uniform(23.0, 27.0, len(pos))
    frames = [bedstruct.Frame(pos, r, box=bedstruct.Box([0, 0, 0], [1200, 300, 400], boundary="pp pp ff"),
                              timestep=ts) for ts in (0, 100)]
    path = tmp_path_factory.mktemp("bed") / "bed.dump"
    bedstruct.write_dump(path, frames)
    return path


@pytest.fixture(scope="module")
def bed_report(bed_dump):
    """The full report on the last frame of ``bed_dump`` (default options), built once for the
    tests that read it, with every figure the sections drew as ``(section key, Figure)``."""
    from bedstruct.report import _model
    shown = []
    real = _model.Section.add_figure

    def keep(self, fig, caption):
        shown.append((self.key, fig))
        return real(self, fig, caption)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(_model.Section, "add_figure", keep)
        mp.setattr(_picture, "render_3d", _note_instead_of_3d)
        rep = build_report(bedstruct.read_dump(bed_dump)[-1])
    return rep, shown


@pytest.fixture(scope="module")
def cli_heat_run(bed_dump, tmp_path_factory):
    """``bedstruct report --heat`` on ``bed_dump`` (no unit system: heat is skipped), run once
    with the summary and heat sections: (exit code, stdout, stderr, output folder)."""
    import io
    out = tmp_path_factory.mktemp("cli") / "rep"
    stdout, stderr = io.StringIO(), io.StringIO()
    with _only("summary", "heat"), contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr), \
            pytest.MonkeyPatch.context() as mp:
        mp.setattr(_picture, "render_3d", _note_instead_of_3d)
        code = main(["report", str(bed_dump), "--heat", "--out", str(out)])
    return code, stdout.getvalue(), stderr.getvalue(), out


def test_select_frames_errors():
    with pytest.raises(ValueError, match="out of range"):
        select_frames(3, "5")
    with pytest.raises(ValueError, match="selects no frame"):
        select_frames(3, "2:1")
    with pytest.raises(ValueError, match="expected"):
        select_frames(3, "last")
    with pytest.raises(ValueError, match="expected 'all', an index or start:stop:step"):
        select_frames(3, "a:b")
    with pytest.raises(ValueError, match="expected"):
        select_frames(3, "0:1:2:3")


def test_cli_option_values_out_of_range_are_usage_errors(bed_dump, tmp_path, capsys):
    for bad in (["--regions", "0"], ["--frames", "last"], ["--german-windows", "2"]):
        assert main(["report", str(bed_dump), "--out", str(tmp_path / "r"), *bad]) == 2
        assert capsys.readouterr().err.startswith("bedstruct report: error:")
    assert not (tmp_path / "r").exists()


def test_report_sections_and_numbers(bed_dump, bed_report, tmp_path):
    frame = bedstruct.read_dump(bed_dump)[-1]
    rep, _ = bed_report                           # default options: 3 regions
    assert rep.settings["regions"] == 3
    status = {s.key: s.status for s in rep.sections}
    assert status["summary"] == "ok" and status["packing"] == "ok" and status["fabric"] == "ok"
    assert status["repose"] == "skipped"          # a flat slab has no pile
    assert "heat" not in status                   # only with heat=True
    num = rep.summary()["values"]
    assert num["summary.n_particles"] == frame.n_particles
    # regional packing fractions bracket the bounding-box fraction sensibly
    for name in ("start", "centre", "end"):
        assert 0.2 < num[f"packing.fraction_{name}"] < 0.74
    # every number carries a unit and a definition
    doc = rep.to_json()
    for sec in doc["sections"].values():
        for q in sec["numbers"].values():
            assert q["unit"] and q["definition"]
    json.dumps(doc, allow_nan=False)
    html_path, json_path = write_report(rep, tmp_path)
    html = html_path.read_text()
    n_figures = sum(len(s.figures) for s in rep.sections)
    assert n_figures > 3 and html.count("data:image/png;base64,") == n_figures + len(rep.pictures)
    assert json.loads(json_path.read_text())["schema"] == "bedstruct.report/1"


def test_report_packing_regions_of_a_lattice_with_a_depleted_end():
    # 24 x 8 x 4 touching spheres (pi/6 everywhere); the last third (x columns 16-23)
    # loses a checkerboard half of its lower three layers: 5/8 of pi/6 there, so a region
    # on the wrong axis, in the wrong order or scaled shows at 1e-12
    lattice = cubic_lattice((24, 8, 4), spacing=50.0, radius=25.0, boundary=("pp", "pp", "ff"))
    site = np.round(lattice.positions / 50.0 - 0.5).astype(int)
    removed = (site[:, 0] >= 16) & (site.sum(axis=1) % 2 == 1) & (site[:, 2] < 3)
    bed = bedstruct.Frame(lattice.positions[~removed], lattice.radii[~removed], box=lattice.box)
    with _only("packing"):
        num = build_report(bed, options=ReportOptions(regions=3)).summary()["values"]
    full = np.pi / 6
    assert num["packing.fraction_start"] == pytest.approx(full, rel=1e-12)
    assert num["packing.fraction_centre"] == pytest.approx(full, rel=1e-12)
    assert num["packing.fraction_end"] == pytest.approx(5 / 8 * full, rel=1e-12)
    assert num["packing.bounding_box_fraction"] == pytest.approx(
        bed.n_particles / lattice.n_particles * full, rel=1e-12)


def test_failing_section_does_not_break_report(bed_dump, monkeypatch):
    def boom(ctx, section):
        raise RuntimeError("kaboom")
    # the sections before, at and after the failing one
    sections = [(k, t, boom if k == "surface" else f) for k, t, f in build_mod.SECTIONS
                if k in ("summary", "packing", "surface", "harmonics")]
    monkeypatch.setattr(build_mod, "SECTIONS", sections)
    rep = build_report(bedstruct.read_dump(bed_dump)[-1])
    assert rep.failed == ["surface"]
    assert "kaboom" in rep.section("surface").error
    assert rep.section("packing").status == "ok" and rep.section("harmonics").status == "ok"
    assert "This section failed" in render_html(rep)


def test_cli_report_json_last_line(bed_dump, tmp_path, capsys):
    out = tmp_path / "rep"
    with _only("summary", "coordination"):
        assert main(["report", str(bed_dump), "--out", str(out), "--json", "--frames", "all",
                     "--german-windows", "8"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    summary = json.loads(last)
    assert summary["values"]["coordination.german_windows"] == 8
    assert summary["sections"]["summary"] == "ok"
    assert summary["values"]["summary.n_frames_selected"] == 2
    assert (out / "report.html").exists() and (out / "report.json").exists()


def test_cli_report_bad_input(tmp_path, capsys):
    bad = tmp_path / "bad.dump"
    bad.write_text("ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n2\nITEM: BOX BOUNDS pp pp pp\n0 1\n0 1\n0 1\n"
                   "ITEM: ATOMS id type x y z radius\n1 1 0.5 0.5 0.5 0.1\n")
    assert main(["report", str(bad), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.dump" in err[0]
    assert main(["report", str(tmp_path / "missing.dump"), "--out", str(tmp_path / "o")]) == 1


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def test_report_renders_in_headless_chromium(bed_report, tmp_path):
    exe = _chromium()
    if exe is None:
        pytest.skip("headless Chromium not installed (Debian package 'chromium'); cannot test rendering")
    rep, _ = bed_report
    html_path, _ = write_report(rep, tmp_path)
    n_fig = sum(len(s.figures) for s in rep.sections) + len(rep.pictures)
    # count images that decoded (naturalWidth > 0) and report console errors via the DOM title
    probe = tmp_path / "probe.html"
    probe.write_text(html_path.read_text().replace(
        "</body>",
        "<script>window.addEventListener('load',()=>{const ok=[...document.images]"
        ".filter(i=>i.complete&&i.naturalWidth>0).length;document.title='loaded:'+ok;"
        "document.body.setAttribute('data-loaded', ok);});</script></body>"))
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={tmp_path / 'profile'}"]
    dom = subprocess.run([exe, *flags, "--virtual-time-budget=5000", "--dump-dom", probe.as_uri()],
                         capture_output=True, text=True, timeout=120)
    assert f'data-loaded="{n_fig}"' in dom.stdout, dom.stderr[-2000:]
    assert "Uncaught" not in dom.stderr
    shot = tmp_path / "report.png"
    subprocess.run([exe, *flags, "--window-size=1200,2400", f"--screenshot={shot}", html_path.as_uri()],
                   capture_output=True, timeout=120)
    assert shot.exists() and shot.stat().st_size > 10_000


def test_repose_section_on_a_pile(tmp_path):
    """A synthetic conical heap of known slope gives its angle; a layer is skipped."""
    rng = np.random.default_rng(3)
    angle = np.radians(30.0)
    pts = rng.uniform([-10, 0, 0], [10, 4, 6], size=(60000, 3))
    pile = pts[pts[:, 2] <= (10 - np.abs(pts[:, 0])) * np.tan(angle)]
    # radius 0.15: the spheres overlap into one network (with 0.05 the cloud is dilute, not a pile)
    frame = bedstruct.Frame(pile, np.full(len(pile), 0.15),
                            box=bedstruct.Box([-12, 0, 0], [12, 4, 8], boundary="ff pp ff"))
    with _only("repose"):
        rep = build_report(frame)
    assert rep.state["kind"] == "pile", rep.state["reason"]
    sec = rep.section("repose")
    assert sec.status == "ok", sec.text
    assert abs(sec.numbers["angle_deg"].value - 30.0) < 1.5


def test_report_along_z_judges_the_input_across_the_bed():
    # --axis z (packing and sizes by height) on a flat slab: a settled bed with its surface
    # measured; on a heap: a pile, and the repose section says which axes it fits along
    slab = cubic_lattice((12, 4, 4), spacing=1.0, radius=0.51, boundary=("ff", "pp", "ff"))
    with _only("surface", "repose"):
        rep = build_report(slab, options=ReportOptions(axis="z"))
    assert rep.state["kind"] == "settled bed", rep.state["reason"]
    assert rep.section("surface").status == "ok"
    lattice = cubic_lattice((40, 4, 20), spacing=1.0, radius=0.51, boundary=("ff", "pp", "ff"))
    x, z = lattice.positions[:, 0], lattice.positions[:, 2]
    heap = lattice.select(z <= 20.0 - np.abs(x - 20.0) * np.tan(np.radians(30)) * 1.5)
    with _only("repose"):
        rep = build_report(heap, options=ReportOptions(axis="z"))
    assert rep.state["kind"] == "pile", rep.state["reason"]
    sec = rep.section("repose")
    assert sec.status == "skipped" and "give --axis x or y" in sec.text, sec.text


def test_heat_section_needs_units_and_reports_each_region(cli_heat_run):
    # bed_dump has no ITEM: UNITS
    heat = json.loads((cli_heat_run[3] / "report.json").read_text())["sections"]["heat"]
    assert heat["status"] == "skipped" and "unit" in heat["text"]
    lattice = cubic_lattice((24, 8, 4), spacing=50.0, radius=25.5, boundary=("ff", "pp", "ff"))
    with _only("heat"):
        rep = build_report(lattice.with_units("micro"), options=ReportOptions(heat=True))
    heat = rep.section("heat")
    assert heat.status == "ok", heat.error
    for name in ("start", "centre", "end"):
        # the pulse starts at 1300 C and the runs stop at a quarter of the excess over 20 C
        assert 20.0 < heat.numbers[f"peak_temperature_{name}"].value < 1300.0
        assert 0.8 < heat.numbers[f"roundness_{name}"].value <= 1.0   # isotropic lattice: round
    assert len(heat.figures) == 3
    # every heat column says its unit: in the JSON (SI) and in the page's headers (natural)
    table = heat.tables[0]
    unit = dict(zip(table.columns, table.units))
    assert (unit["peak_temperature_C"], unit["crossing_time"], unit["major_axis"], unit["k_max"]) == (
        "degC", "s", "m", "W/(m K)")
    page = render_html(rep)
    assert "peak_temperature_C (°C)" in page and "k_max (W/(m K))" in page and "major_axis (µm)" in page


def test_cli_missing_optional_dependency_is_one_line(tmp_path, capsys, monkeypatch):
    import builtins
    real_import = builtins.__import__

    def no_zstd(name, *args, **kwargs):
        if name.startswith("zstandard"):
            raise ImportError("No module named 'zstandard'")
        return real_import(name, *args, **kwargs)

    path = tmp_path / "bed.dump.zst"
    path.write_bytes(b"\x28\xb5\x2f\xfd")
    monkeypatch.setattr(builtins, "__import__", no_zstd)
    assert main(["info", str(path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "zstandard" in err[0]


def test_cli_out_that_is_a_file_is_an_error_not_a_traceback(bed_dump, cli_heat_run, tmp_path, capsys):
    taken = tmp_path / "taken"
    taken.write_text("")
    assert main(["report", str(bed_dump), "--out", str(taken)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("bedstruct report: error:") and "taken" in err[0]
    code, _, _, out = cli_heat_run                  # a folder that is not there yet is made
    assert code == 0
    mode = (out / "report.html").stat().st_mode & 0o777
    assert mode & 0o044 == 0o044 & ~bedstruct._atomic._UMASK   # readable as the umask allows


def test_repose_sample_is_measured_on_its_pile_not_on_falling_clumps():
    # the bundled pile (data/samples/README.md: its run's three replicates give 29.9 +- 1.0 deg)
    # has a few clumps still falling below its ledge; they must not set the base (39.5 deg)
    from pathlib import Path
    sample = Path(__file__).parents[2] / "data" / "samples" / "repose" / "pile.dump.gz"
    frame = bedstruct.read_dump(sample, units="si")[-1]
    with _only("repose"):
        sec = build_report(frame).section("repose")
    assert sec.status == "ok", sec.text
    assert sec.numbers["angle_deg"].value == pytest.approx(29.9, abs=2.0)
    assert "largest cluster" in sec.text
    # one function: the report's angle is pile_angle's, and its +- is named for what it is
    from bedstruct.analysis import pile_angle
    p = pile_angle(frame)
    assert sec.numbers["angle_deg"].value == p.angle_deg
    assert sec.numbers["angle_std_deg"].value == p.angle_std_deg
    assert "fit uncertainty" in sec.numbers["angle_std_deg"].definition
    assert "not a scatter between piles" in sec.numbers["angle_std_deg"].definition
    assert sec.numbers["flank_difference_deg"].value == pytest.approx(
        abs(sec.numbers["left_deg"].value - sec.numbers["right_deg"].value))


def test_cli_heat_skipped_for_unknown_units_is_said_on_stderr(bed_dump, cli_heat_run, tmp_path):
    code, _, err, _ = cli_heat_run
    assert code == 0
    assert "warning: --heat skipped" in err and "unit" in err
    with pytest.raises(SystemExit) as exc:       # an unknown unit style is a usage error
        main(["report", str(bed_dump), "--units", "furlong", "--out", str(tmp_path / "s")])
    assert exc.value.code == 2


def test_d50_shift_is_none_when_the_end_region_is_empty():
    # periodic along x: the regions span the box, and the last third holds no particle
    f = bedstruct.Frame([[10, 5, 5], [20, 5, 5], [30, 5, 5], [45, 5, 5]], [2, 2, 3, 3.0],
                        box=bedstruct.Box([0, 0, 0], [100, 10, 10], boundary="pp pp ff"))
    with _only("psd"):
        sec = build_report(f).section("psd")
    assert [row[1] for row in sec.tables[0].rows] == [3, 1, 0]
    assert sec.numbers["d50_shift_start_to_end"].value is None     # not centre minus start


def _falling_gas(n=100, speed=0.5):
    """100 spheres of 50 um far apart (packing ~0.01, no contacts), falling: a dilute flow."""
    rng = np.random.default_rng(4)
    g = np.stack(np.meshgrid(*[np.arange(5)] * 3, indexing="ij"), -1).reshape(-1, 3)[:n]
    pos = (g + 0.5) * 200e-6 + rng.normal(0, 5e-6, (n, 3))
    v = np.zeros((n, 3))
    v[:, 2] = -speed
    return bedstruct.Frame(pos, np.full(n, 25e-6), box=bedstruct.Box([0, 0, 0], [1e-3] * 3, boundary="pp pp ff"),
                           velocities=v).with_units("si")


def _static_numbers(rep):
    return [k for k in rep.summary()["values"] if k.startswith(("coordination.german", "surface.", "repose."))]


def test_a_dilute_flow_is_not_reported_as_a_bed(tmp_path):
    rep = build_report(_falling_gas())
    assert rep.state["kind"] == "dilute flow"
    assert rep.summary()["input_kind"] == "dilute flow"
    for key in ("coordination", "surface", "fabric", "harmonics", "repose"):
        sec = rep.section(key)
        assert sec.status == "not meaningful" and sec.text.startswith("Not meaningful for a dilute flow")
        assert not sec.numbers and not sec.figures
    assert _static_numbers(rep) == []                          # no German a = 0, b = 0
    assert rep.section("packing").status == "ok"
    assert rep.section("psd").status == "not meaningful" and "monodisperse" in rep.section("psd").text
    html_path, json_path = write_report(rep, tmp_path)
    doc = json.loads(json_path.read_text())
    assert doc["input_state"]["kind"] == "dilute flow"
    assert doc["input_state"]["evidence"]["mean_coordination"]["value"] == 0.0
    assert "german" in doc["input_state"]["not_meaningful"]
    html = html_path.read_text()
    assert "<b>Input: dilute flow</b>" in html and html.index("Input: dilute flow") < html.index('id="summary"')
    assert '<span class="status not-meaningful">not meaningful</span>' in html


def test_a_bed_still_settling_is_not_reported_as_a_bed():
    # the slab of `bed_dump`, every particle moving at 0.13 m/s (4 sqrt(g d) for 50 um spheres)
    rng = np.random.default_rng(1)
    g = np.stack(np.meshgrid(*[np.arange(k) for k in (24, 6, 4)], indexing="ij"), -1).reshape(-1, 3)
    pos = ((g + 0.5) * 50.0 + rng.normal(0, 2.0, g.shape)) * 1e-6
    v = rng.normal(0, 0.03, g.shape) + [0, 0, -0.13]
    frame = bedstruct.Frame(pos, rng.uniform(23.0, 27.0, len(pos)) * 1e-6, velocities=v,
                            box=bedstruct.Box([0, 0, 0], [1.2e-3, 0.3e-3, 0.4e-3], boundary="pp pp ff")).with_units("si")
    judged = ("coordination", "surface", "repose", "heat")     # those not meaningful for it
    with _only(*judged):
        rep = build_report(frame, options=ReportOptions(heat=True))
    assert rep.state["kind"] == "moving bed"
    assert {s.key for s in rep.sections if s.status == "not meaningful"} == set(judged)
    assert rep.section("coordination").status == "not meaningful"
    assert rep.section("heat").status == "not meaningful"
    assert _static_numbers(rep) == []
    # the same positions at rest are a settled bed with German's fit
    still = bedstruct.Frame(frame.positions, frame.radii, box=frame.box, velocities=v * 1e-3).with_units("si")
    with _only("coordination"):
        rep = build_report(still)
    assert rep.state["kind"] == "settled bed"
    assert rep.section("coordination").status == "ok"
    assert "german_a" in rep.section("coordination").numbers


def test_report_german_fit_is_the_library_default_and_says_its_windows(bed_dump, bed_report):
    from bedstruct.analysis import GERMAN_WINDOWS, german_law_along
    frame = bedstruct.read_dump(bed_dump)[-1]
    sec = bed_report[0].section("coordination")
    lib = german_law_along(frame)
    assert lib.n_windows == GERMAN_WINDOWS
    assert sec.numbers["german_a"].value == lib.fit.a and sec.numbers["german_b"].value == lib.fit.b
    assert sec.numbers["german_windows"].value == lib.n_used
    assert lib.definition in sec.numbers["german_windows"].definition
    assert f"over {lib.n_used} windows along x" in sec.numbers["german_a"].definition
    assert lib.fit.determined and sec.numbers["german_determined"].value is True
    assert "not separately determined" not in sec.text
    # a different number of windows is a stated option, and gives the library's numbers for it
    with _only("coordination"):
        sec8 = build_report(frame, options=ReportOptions(german_windows=8)).section("coordination")
    assert sec8.numbers["german_a"].value == german_law_along(frame, n_windows=8).fit.a
    assert sec8.numbers["german_a"].value != lib.fit.a


def test_harmonic_figure_plots_the_table_with_region_names(bed_dump, bed_report):
    rep, shown = bed_report
    sec = rep.section("harmonics")
    assert sec.status == "ok", sec.text
    table = sec.tables[0]
    assert table.columns[:3] == ["region", "x from", "x to"] and table.units[1:3] == ["unknown", "unknown"]
    assert table.columns[3:] == ["contacts", "P_2/P_0", "P_4/P_0", "P_6/P_0", "P_8/P_0"]
    assert [row[1] for row in table.rows][1:] == [row[2] for row in table.rows][:-1]     # adjoining regions
    # the contacts of the regions, against which the sampling floor (2l + 1)/M is read
    from bedstruct.analysis import contact_regions
    ctx = build_mod._Context([bedstruct.read_dump(bed_dump)[-1]], None, ReportOptions(), [0])
    labels, _ = contact_regions(ctx.contacts.touching(), ctx.frame, axis=0, n_regions=3)
    assert [row[3] for row in table.rows] == [int(np.count_nonzero(labels == k)) for k in range(3)]
    (fig,) = [f for key, f in shown if key == "harmonics"]
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == [row[0] for row in table.rows] == ["start", "centre", "end"]
    lines = {ln.get_label(): ln.get_ydata() for ln in ax.get_lines()}
    for c, col in enumerate(table.columns[4:], start=4):
        l = col.split("/")[0][2:]
        np.testing.assert_array_equal(lines[f"l = {l}"], [row[c] for row in table.rows])
    # the headline numbers are the same normalisation: P_l/P_0 of all contacts, not P_l
    from bedstruct.analysis import harmonic_expansion
    c = build_mod._Context([bedstruct.read_dump(bed_dump)[-1]], None, ReportOptions(), [0]).contacts.touching()
    e = harmonic_expansion(c.normals, 8)
    assert sec.numbers["power_l4"].value == pytest.approx(e.power[4] / e.power[0], rel=1e-12)
    assert sec.numbers["power_l4"].value == pytest.approx(4 * np.pi * e.power[4], rel=1e-12)


def test_fabric_roses_plot_the_regions_of_the_table(bed_report):
    """Each region's rank-2 rose reaches 4 pi f_2 = 1 + 15/2 (lambda_1 - 1/3) along its
    principal direction, with lambda_1 from the section's table (the grid of the rose
    passes within 3 degrees of that direction)."""
    rep, shown = bed_report
    sec = rep.section("fabric")
    assert sec.status == "ok", sec.text
    table = sec.tables[0]
    assert table.columns[:3] == ["region", "contacts", "λ1"]
    grid = [f for key, f in shown if key == "fabric"][0]
    roses = [a for a in grid.axes if a.name == "3d"]
    assert len(roses) == 3 * len(table.rows)
    reach = []
    for row, ax in zip(table.rows, roses[::3]):
        assert ax.get_title() == f"{row[0]}: rank 2"
        (surface,) = ax.collections
        corners = surface._faces            # (cells, 4, 3): the quadrilaterals as drawn
        reach.append(float(np.linalg.norm(corners, axis=-1).max()))
    expected = [1 + 7.5 * (row[2] - 1 / 3) for row in table.rows]
    np.testing.assert_allclose(reach, expected, rtol=2e-3)
    assert max(expected) - min(expected) > 0.05         # the regions differ: a mix-up shows


@pytest.mark.parametrize("style, factor", [("si", 1.0), ("cgs", 1e2), ("micro", 1e6), ("nano", 1e9)])
def test_number_density_is_shown_per_cubic_millimetre_in_every_unit_system(tmp_path, style, factor):
    # 8 x 6 x 4 spheres 100 um apart, the centres spanning 0.7 x 0.6 (periodic) x 0.3 mm:
    # 1524 per mm^3 on the page, in the dump's unit in the JSON
    lattice = cubic_lattice((8, 6, 4), spacing=100e-6 * factor, radius=51e-6 * factor,
                            boundary=("ff", "pp", "ff"))
    with _only("rdf"):
        rep = build_report(lattice.with_units(style))
    density = rep.section("rdf").numbers["density"]
    unit = {"si": "m", "cgs": "cm", "micro": "um", "nano": "nm"}[style]
    assert density.unit == f"1/{unit}^3"
    assert density.value == pytest.approx(192 / (0.7 * 0.6 * 0.3) * 1e9 / factor ** 3, rel=1e-9)
    page = render_html(rep)
    shown = re.search(r'<td>density</td><td class="num">([^<]*)</td><td>([^<]*)</td>', page)
    assert shown is not None and shown.group(2) == "1/mm³", page
    assert shown.group(1) == "1524", shown.group(1)


def test_html_shows_natural_units_and_json_keeps_si(tmp_path):
    # 100 um spheres in metres: the page says um and mm, never 1e-04 or a numpy array
    lattice = cubic_lattice((24, 6, 4), spacing=100e-6, radius=51e-6, boundary=("ff", "pp", "ff"))
    rep = build_report(lattice.with_units("si"))
    html_path, json_path = write_report(rep, tmp_path)
    page = html_path.read_text()
    import re
    cells = re.findall(r'<td class="num">([^<]*)</td>', page)
    assert cells and not [c for c in cells if re.search(r"\de[-+]\d", c)], "e-notation in a table cell"
    assert not [c for c in cells if re.search(r"\d \d|\[\s*-?\d+\.\s", c)], "numpy array printing"
    text = re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]+", "", page)
    assert not re.search(r"\bnan\b", text, flags=re.I)        # no nan, nor nan +- nan
    assert '<td class="num">[51, 51]</td><td>µm</td>' in page                    # radius_range
    assert "51 µm (monodisperse)" in page                                        # psd
    assert '<td class="num">2.4</td><td>mm</td>' in page or "[2.4, 0.6, 0.4]" in page   # box_hi
    doc = json.loads(json_path.read_text())
    summary = doc["sections"]["summary"]["numbers"]
    assert summary["radius_range"] == {"value": [51e-6, 51e-6], "unit": "m",
                                       "definition": "smallest and largest sphere radius"}
    assert not doc["sections"]["psd"]["tables"]                 # one size: no size table
    # two sizes: the size table in the JSON stays in metres
    radii = np.where(np.arange(lattice.n_particles) % 2, 51e-6, 45e-6)
    poly = bedstruct.Frame(lattice.positions, radii, box=lattice.box).with_units("si")
    _, json_poly = write_report(build_report(poly), tmp_path / "poly")
    psd_table = json.loads(json_poly.read_text())["sections"]["psd"]["tables"][0]
    assert psd_table["units"] == ["", "1", "m", "m", "m"]
    assert 90e-6 <= psd_table["rows"][0][3] <= 102e-6


def test_a_section_whose_numbers_are_all_nan_is_not_ok(monkeypatch):
    from bedstruct.report._model import run_section

    def only_nan(sec):
        sec.add_number("x", float("nan"), "m", "a length")
        sec.add_number("y", [float("nan"), None], "1", "two ratios")
        sec.add_number("label", "text", "-", "a label")

    sec = run_section("k", "K", only_nan)
    assert sec.status == "skipped" and not sec.numbers and sec.text.startswith("No number could be computed")
    sec = run_section("k", "K", lambda s: s.add_number("x", 1.0, "m", "a length"))
    assert sec.status == "ok"


def test_repose_skip_text_has_no_nan():
    # a flat slab: the slope test fails; its reason must not read "nan +- nan"
    lattice = cubic_lattice((24, 6, 4), spacing=1.0, radius=0.51, boundary=("ff", "pp", "ff"))
    with _only("repose"):
        sec = build_report(lattice).section("repose")
    assert sec.status == "skipped" and "nan" not in sec.text.lower()


def test_height_map_has_axes_units_and_true_aspect():
    from bedstruct.analysis import surface_height_map
    from bedstruct.plot import plot_height_map
    lattice = cubic_lattice((24, 6, 4), spacing=100e-6, radius=51e-6, boundary=("ff", "pp", "ff"))
    fig, ax = plot_height_map(surface_height_map(lattice), unit="mm", scale=1e3)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (mm)", "y (mm)")
    assert ax.get_aspect() == 1.0
    x0, x1, y0, y1 = ax.images[0].get_extent()
    assert (x1 - x0, y1 - y0) == pytest.approx((2.4, 0.6), rel=0.05)
    assert "mm" in fig.axes[1].get_xlabel() + fig.axes[1].get_ylabel()       # the colour bar


def test_cli_report_says_where_it_wrote_and_what_the_input_is(cli_heat_run):
    code, stdout, _, out = cli_heat_run
    assert code == 0
    lines = stdout.strip().splitlines()
    assert lines == [f"bedstruct report: wrote {out / 'report.html'} and {out / 'report.json'} "
                     f"(input: settled bed)"]


def test_rdf_section_of_a_lattice_bed_has_its_first_shell_at_one_diameter():
    from bedstruct.analysis import radial_distribution
    lattice = cubic_lattice((24, 6, 4), spacing=100e-6, radius=50e-6, boundary=("ff", "pp", "ff"))
    with _only("rdf"):
        sec = build_report(lattice.with_units("si")).section("rdf")
    assert sec.status == "ok", sec.text
    assert sec.numbers["peak_r_over_d50"].value == pytest.approx(1.0, abs=0.05)
    assert sec.numbers["peak_r"].value == radial_distribution(lattice).first_peak[0]
    assert sec.numbers["peak_r"].unit == "m" and len(sec.figures) == 1


def test_voronoi_section_of_a_lattice_bed_is_pi_over_6_inside(monkeypatch):
    pytest.importorskip("pyvoro2", reason="optional extra bedstruct[voronoi] (pyvoro2) not installed")
    lattice = cubic_lattice((12, 4, 4), spacing=100e-6, radius=50e-6, boundary=("pp", "pp", "ff"))
    with _only("voronoi"):
        sec = build_report(lattice.with_units("si")).section("voronoi")
    assert sec.status == "ok", sec.text
    assert sec.numbers["mean_inside"].value == pytest.approx(np.pi / 6, rel=1e-9)
    assert sec.numbers["mean_all"].value == pytest.approx(np.pi / 6, rel=1e-9)   # the region ends at the caps
    assert sec.numbers["wall_cell_fraction"].value == pytest.approx(0.5)          # top and bottom layers
    assert len(sec.figures) == 1


def test_voronoi_section_without_pyvoro2_is_skipped_with_the_install_hint(monkeypatch):
    import builtins
    real = builtins.__import__

    def no_pyvoro2(name, *args, **kwargs):
        if name == "pyvoro2":
            raise ImportError("No module named 'pyvoro2'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_pyvoro2)
    lattice = cubic_lattice((6, 4, 4), spacing=1.0, radius=0.5, boundary=("pp", "pp", "ff"))
    with _only("voronoi"):
        sec = build_report(lattice).section("voronoi")
    assert sec.status == "skipped" and "bedstruct[voronoi]" in sec.text


def test_cli_report_lenient_lists_the_frames_it_left_out(bed_dump, tmp_path, capsys):
    """Frames with a non-numeric value and a wrong atom count between the good ones: strict
    stops with the file and line; --lenient reports on the good frames and lists both."""
    good = bed_dump.read_text()
    second = good.index("ITEM: TIMESTEP", 1)
    one = good[:second]                                 # frame at timestep 0
    garbled = one.replace("ITEM: TIMESTEP\n0\n", "ITEM: TIMESTEP\n50\n", 1)
    rows = garbled.splitlines(keepends=True)
    rows[30] = rows[30].replace(".", ",", 1)            # a non-numeric value on line 31
    short = one.replace("ITEM: TIMESTEP\n0\n", "ITEM: TIMESTEP\n70\n", 1)
    short = short[:short.rindex("\n", 0, len(short) - 1) + 1]   # one row fewer than the count
    path = tmp_path / "damaged.dump"
    path.write_text(one + "".join(rows) + short + good[second:])
    n_one = one.count("\n")
    # strict reads only the frames selected: all of them here, so the first bad one stops it
    assert main(["report", str(path), "--out", str(tmp_path / "strict"), "--frames", "all"]) == 1
    err = capsys.readouterr().err
    assert f"{path}, line {n_one + 31}: non-numeric value" in err
    with pytest.warns(UserWarning, match="skipping a malformed frame"), _only("summary"):
        assert main(["report", str(path), "--out", str(tmp_path / "r"), "--lenient", "--json"]) == 0
    out, err = capsys.readouterr()
    assert "2 malformed frame(s) left out" in err
    summary = json.loads(out.strip().splitlines()[-1])
    expected = [(50, n_one + 31), (70, 3 * n_one)]   # 70: where the next frame begins
    assert [(k["timestep"], k["line"]) for k in summary["skipped_frames"]] == expected
    doc = json.loads((tmp_path / "r" / "report.json").read_text())
    assert doc["inputs"]["frames_in_input"] == 2
    assert [(k["timestep"], k["line"]) for k in doc["inputs"]["skipped_frames"]] == expected
    assert summary["values"]["summary.timestep"] == 100
    html = (tmp_path / "r" / "report.html").read_text()
    assert 'id="skipped-frames"' in html and "2 malformed frame(s) left out" in html
    assert "atom count mismatch" in html and "non-numeric value" in html


# ---------------------------------------------------------------- pictures of the bed
def _png_pixels(uri_or_png):
    """The RGB(A) pixels of a PNG (bytes or data URI) as floats in [0, 1]."""
    import base64
    import io
    from matplotlib.image import imread
    png = (base64.b64decode(uri_or_png.split(",", 1)[1]) if isinstance(uri_or_png, str)
           else uri_or_png)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    return imread(io.BytesIO(png), format="png")


def _si_slab(n=(8, 3, 2), radius=25e-6):
    """A small slab of touching spheres in SI units (diameters 50 um, the first row 80 um)."""
    frame = cubic_lattice(n, spacing=2 * radius, radius=radius, boundary=("pp", "pp", "ff"))
    radii = np.full(frame.n_particles, radius)
    radii[frame.positions[:, 0] < 2 * radius] = 40e-6
    return bedstruct.Frame(frame.positions, radii, box=frame.box, units="si")


def test_side_view_draws_every_sphere_at_its_size_coloured_by_diameter_in_um():
    from matplotlib.collections import EllipseCollection
    from bedstruct.report._picture import side_view
    frame = _si_slab()
    fig = side_view(frame, axis=0, scale=1e6, unit="µm")
    ax = fig.axes[0]
    (discs,) = [c for c in ax.collections if isinstance(c, EllipseCollection)]
    assert len(discs.get_offsets()) == frame.n_particles
    # x along the bed, z up, in um; each disc as wide as its sphere
    np.testing.assert_allclose(np.sort(discs.get_widths()), np.sort(2 * frame.radii * 1e6))
    np.testing.assert_allclose(discs.get_offsets(), frame.positions[np.argsort(
        -frame.positions[:, 1], kind="stable")][:, [0, 2]] * 1e6)   # far ones (large y) first
    np.testing.assert_allclose(np.sort(discs.get_array()), np.sort(2 * frame.radii * 1e6))
    assert set(np.round(discs.get_array(), 9)) == {50.0, 80.0}
    assert ax.get_xlabel() == "x (µm)" and ax.get_ylabel() == "z (µm)"
    lo, hi = ax.get_xlim()
    assert lo <= (frame.positions[:, 0].min() - 40e-6) * 1e6 + 1e-9
    assert hi >= (frame.positions[:, 0].max() + 40e-6) * 1e6 - 1e-9
    assert "particle diameter (µm)" in fig.axes[1].get_ylabel()


def test_report_has_the_side_view_at_the_top_without_3d(monkeypatch):
    monkeypatch.setattr(build_mod, "SECTIONS", build_mod.SECTIONS[:1])   # the pictures only
    rep = build_report(_si_slab(), options=ReportOptions(view_3d=False))
    assert [c.split(" (")[0] for c, _ in rep.pictures] == ["Side view of the bed along x"]
    pixels = _png_pixels(rep.pictures[0][1])
    assert pixels.shape[0] > 100 and np.ptp(pixels[..., :3]) > 0.5     # a picture, not blank
    assert "turned off" in rep.picture_note
    html = render_html(rep)
    assert html.index('id="bed-pictures"') < html.index("<section")
    assert "turned off" in html
    assert rep.to_json()["pictures"]["captions"] == [rep.pictures[0][0]]


def test_report_says_why_there_is_no_3d_view_without_pyvista(monkeypatch):
    import importlib.util
    real = importlib.util.find_spec
    monkeypatch.setattr(_picture, "render_3d", _REAL_RENDER_3D)
    monkeypatch.setattr(build_mod, "SECTIONS", build_mod.SECTIONS[:1])
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "pyvista" else real(name, *a))
    rep = build_report(_si_slab())
    assert len(rep.pictures) == 1 and rep.pictures[0][0].startswith("Side view")
    assert "3-D view not drawn: it needs pyvista (pip install 'bedstruct[interop]')" in rep.picture_note
    assert "it needs pyvista" in render_html(rep)


def test_3d_view_renders_off_screen_when_pyvista_is_importable():
    pytest.importorskip("pyvista")
    png, note = _REAL_RENDER_3D(_si_slab())
    if png is None and "no display, and no Xvfb" in note:
        pytest.skip(note)
    assert png is not None, note
    assert note.startswith("3-D view rendered off screen with PyVista")
    pixels = _png_pixels(png)[..., :3]
    assert pixels.shape[:2] == (640, 1000)
    drawn = np.any(pixels < 0.95, axis=-1)             # not the white background
    assert 0.02 < drawn.mean() < 0.9
    # two sizes, two colours of viridis: the 80 um row is yellow-green, the rest dark blue
    colours = pixels[drawn]
    assert (colours[:, 1] > 0.6).any() and ((colours[:, 2] > colours[:, 0]) & (colours[:, 1] < 0.4)).any()


def test_html_numbers_are_readable_and_float_noise_shows_as_zero():
    """Significant digits, scientific notation for very small and very large numbers, and a
    value that is rounding noise against its scale (its column, its list, 1 for a
    dimensionless number) shown as 0; a probability is never rounded to 0."""
    import re

    from bedstruct.report._model import Report, Section, Table
    from bedstruct.report._render import _number

    assert _number(0.0853412) == "0.08534" and _number(29.84) == "29.84"
    assert _number(1.62e-17) == "1.62e-17" and _number(-1.2e-7) == "-1.2e-7"
    assert _number(3.2e16) == "3.2e+16" and _number(123456.7) == "123,500"
    assert _number(-2.84e-14, scale=72.6) == "0" and _number(2e-5, scale=1.0) == "2e-5"
    sec = Section("s", "S")
    sec.add_number("segregation_index", 1.48e-16, "1", "a dimensionless index")
    sec.add_number("p_gap", 1.6e-17, "1", "a p-value")
    sec.add_number("p_values", [0.5, 1.6e-17], "1", "two p-values")
    sec.add_number("box_lo", [-2.7e-20, 2.5e-4, 0.0], "m", "lower box bounds")
    sec.tables.append(Table(["effect", "magnitude", "dchi2", "p", "BIC weight"],
                            [["a", 0.0853, 72.6, 1.62e-17, 0.317],
                             ["b", 3.29e-22, -2.84e-14, 0.5, 7.09e-17]]))
    page = render_html(Report("t", inputs={}, settings={}, sections=[sec]))
    assert not re.search(r"0\.0000\d", page), re.search(r"0\.0000\d", page)
    cells = re.findall(r'<td class="num">([^<]*)</td>', page)
    assert cells[:4] == ["0", "1.6e-17", "[0.5, 1.6e-17]", "[0, 250, 0]"]
    assert cells[4:] == ["a", "0.0853", "72.6", "1.62e-17", "0.317",
                         "b", "0", "0", "0.5", "7.09e-17"]


# ------------------------------------------------- 2-D runs, tilted boxes, too few particles
def _held_discs(nx=24, ny=8, spacing=0.99):
    """Discs of diameter 1 on a triangular lattice, overlapping by 1 %, at z = 0 in a periodic
    z box thinner than a diameter (a LAMMPS 2-D run)."""
    rows = [[(i + 0.5 * (j % 2) + 0.25) * spacing, (j + 0.5) * spacing * np.sqrt(3) / 2, 0.0]
            for j in range(ny) for i in range(nx)]
    box = bedstruct.Box([0, 0, -0.28], [nx * spacing, ny * spacing * np.sqrt(3) / 2, 0.28])
    return bedstruct.Frame(np.array(rows), np.full(nx * ny, 0.5), box=box)


def test_a_2d_run_reports_area_fractions_and_no_3d_analysis():
    with _only("packing", "coordination", "rdf", "voronoi", "surface", "fabric", "harmonics", "repose"):
        rep = build_report(_held_discs())
    assert rep.state["dimension"] == 2 and "2-D run" in rep.state["reason"]
    # the area fraction of the triangular lattice, pi / (2 sqrt 3) over the spacing squared
    phi = np.pi / (2 * np.sqrt(3)) / 0.99 ** 2
    pk = rep.section("packing")
    assert pk.status == "ok" and "bounding_box_fraction" not in pk.numbers
    assert pk.numbers["bounding_box_area_fraction"].value == pytest.approx(phi, rel=1e-12)
    for name in ("start", "centre", "end"):    # whole periods of the lattice along x
        assert pk.numbers[f"area_fraction_{name}"].value == pytest.approx(phi, rel=1e-9)
    co = rep.section("coordination")
    assert co.status == "ok" and co.numbers["mean"].value == pytest.approx(6.0)   # in the plane
    assert "german_a" not in co.numbers and "2-D run" in co.text
    for key in ("rdf", "voronoi", "surface", "fabric", "harmonics", "repose"):
        sec = rep.section(key)
        assert sec.status == "not meaningful" and sec.text.startswith("Not meaningful for a 2-D ")
        assert not sec.numbers


def test_the_lammps_2d_example_is_not_read_as_spheres_touching_their_images(realdata):
    frame = bedstruct.read(realdata / "ashriva16+granular-force-chains/LAMMPS/examples/visualize.du")[-1]
    rep = build_report(frame, options=ReportOptions(view_3d=False))
    assert rep.failed == []
    assert rep.state["dimension"] == 2
    # discs 1.1225 apart with diameter 1: no contacts, the area fraction of the 2-D packing
    assert rep.state["evidence"]["mean_coordination"].value == 0.0
    assert rep.section("packing").numbers["bounding_box_area_fraction"].value == pytest.approx(0.7198, abs=1e-4)
    values = rep.summary()["values"]
    assert not [k for k in values if k.startswith(("coordination.", "fabric.", "harmonics.", "rdf.",
                                                     "surface.", "voronoi."))]


def test_a_tilted_box_is_judged_and_gated_as_its_orthogonal_copy():
    gas = _falling_gas()
    tilted = bedstruct.Frame(gas.positions, gas.radii, box=gas.box.replace(tilt=np.array([1e-5, 0, 0])),
                             velocities=gas.velocities, units=gas.units)
    with _only("packing", "coordination", "surface", "fabric", "harmonics", "repose"):
        a, b = build_report(gas), build_report(tilted)
    assert a.state["kind"] == b.state["kind"] == "dilute flow"
    assert a.state["not_meaningful"] == b.state["not_meaningful"]
    assert {s.key: s.status for s in a.sections} == {s.key: s.status for s in b.sections}
    assert b.section("packing").numbers["bounding_box_fraction"].value == pytest.approx(
        a.section("packing").numbers["bounding_box_fraction"].value, rel=1e-12)


def test_the_side_view_shows_mm_spheres_in_mm():
    from bedstruct.report._picture import diameters_shown, side_view
    frame = cubic_lattice((4, 2, 2), spacing=5e-3, radius=2.5e-3, boundary=("pp", "pp", "ff"))
    frame = bedstruct.Frame(frame.positions, frame.radii, box=frame.box, units="si")
    sizes = diameters_shown(frame)
    assert sizes.unit == "mm" and np.allclose(sizes.values, 5.0)
    fig = side_view(frame, scale=1e3, unit="mm")
    assert fig.axes[1].get_ylabel() == "particle diameter (mm)"
    assert diameters_shown(_si_slab()).unit == "µm"          # 50 um spheres stay in um


def test_an_empty_frame_is_an_error_not_a_report(tmp_path, capsys):
    empty = bedstruct.Frame(np.zeros((0, 3)), np.zeros(0), box=[1, 1, 1], timestep=7)
    with pytest.raises(ValueError, match=r"the frame analysed \(timestep 7\) has no particles"):
        build_report(empty)
    path = tmp_path / "empty.dump"
    bedstruct.write_dump(path, [empty])
    assert main(["report", str(path), "--no-3d", "--out", str(tmp_path / "r")]) == 1
    assert "has no particles" in capsys.readouterr().err
    assert not (tmp_path / "r" / "report.html").exists()


def test_centres_on_a_line_skip_the_rdf_with_the_reason():
    f = bedstruct.Frame([[k + 0.5, 1, 1] for k in range(12)], np.full(12, 0.5),
                        box=bedstruct.Box([0, 0, 0], [12, 2, 2], boundary="ff ff ff"))
    with _only("rdf"):
        sec = build_report(f).section("rdf")
    assert sec.status == "skipped" and "span no volume" in sec.text


@pytest.mark.parametrize("n", [1, 2])
def test_a_handful_of_particles_gives_no_packing_or_rdf(n):
    f = bedstruct.Frame([[1.0 + 3 * k, 1, 1] for k in range(n)], np.full(n, 0.5),
                        box=bedstruct.Box([0, 0, 0], [10, 2, 2], boundary="ff ff ff"))
    with _only("packing", "rdf", "voronoi", "psd"):
        rep = build_report(f)
    for key in ("packing", "rdf", "voronoi"):
        sec = rep.section(key)
        assert sec.status == "not meaningful" and "fewer than 10" in sec.text and not sec.numbers
    assert rep.section("psd").status == "not meaningful" and "monodisperse" in rep.section("psd").text


def test_an_input_that_cannot_be_judged_reports_no_state_dependent_numbers(monkeypatch):
    import bedstruct.analysis as analysis

    def broken(*a, **k):
        raise RuntimeError("no judgement")
    monkeypatch.setattr(analysis, "bed_state", broken)
    with _only("packing", "coordination", "surface"):
        rep = build_report(_si_slab())
    assert rep.state["kind"] == "unknown"
    for key in ("coordination", "surface"):
        sec = rep.section(key)
        assert sec.status == "not meaningful" and "could not be judged" in sec.text and not sec.numbers
    assert rep.section("packing").status == "ok"


def test_a_particle_apart_from_the_bed_is_left_out_of_german_s_windows():
    # one sphere far above a settled slab: the enclosing box reaches up to it (the packing
    # fractions say so), German's law is fitted over the bed without it
    lattice = cubic_lattice((24, 4, 4), spacing=1.0, radius=0.51, boundary=("ff", "pp", "ff"))
    x, z = lattice.positions[:, 0], lattice.positions[:, 2]
    slab = lattice.select((x < 12) | (z < 3))      # the second half one layer thinner
    pos = np.vstack([slab.positions, [[12.0, 2.0, 60.0]]])
    stray = bedstruct.Frame(pos, np.append(slab.radii, 0.51), box=bedstruct.Box(
        [0, 0, 0], [24, 4, 64], boundary="ff pp ff"))
    with _only("packing", "coordination"):
        ref = build_report(slab)
        rep = build_report(stray)
    assert "1 particle lies apart from the bed" in rep.section("packing").text
    assert "apart" not in (ref.section("packing").text or "")
    got, want = rep.section("coordination").numbers, ref.section("coordination").numbers
    for key in ("german_a", "german_b"):
        assert got[key].value == pytest.approx(want[key].value), key
    assert 0 < want["german_b"].value < 10, want["german_b"].value
    assert "1 particle apart from the bed left out" in got["german_windows"].definition


def test_report_says_when_the_windows_do_not_determine_german_a_and_b():
    # spheres of 50 um touching on a lattice: every window's packing within 0.01 of the others
    rng = np.random.default_rng(0)
    d, n, nz = 50e-6, 8, 3
    a = d * np.sqrt(2.0)
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]]) * a
    cells = np.stack(np.meshgrid(np.arange(n), np.arange(n), np.arange(nz), indexing="ij"), -1).reshape(-1, 3)
    pos = (cells[:, None, :] * a + basis[None]).reshape(-1, 3) + 0.5 * d
    pos += rng.normal(0, 0.002 * d, pos.shape)
    frame = bedstruct.Frame(pos, np.full(len(pos), 0.5005 * d),
                            box=bedstruct.Box([0, 0, 0], [n * a, n * a, nz * a + 2 * d], boundary="pp pp ff"),
                            velocities=np.zeros_like(pos)).with_units("si")
    with _only("coordination"):
        sec = build_report(frame).section("coordination")
    from bedstruct.analysis import german_law_along
    fit = german_law_along(frame, check_state=False).fit
    assert not fit.determined
    assert sec.numbers["german_determined"].value is False
    assert fit.undetermined_reason in sec.text and "mean coordination" in sec.text
    assert sec.numbers["german_a"].value == fit.a     # still listed, with its interval


def test_region_bounds_within_rounding_of_zero_show_as_zero():
    from types import SimpleNamespace
    from bedstruct.report.build import _regions_text
    profile = SimpleNamespace(lower=[[-7.051e-14, 0, 0], [6.2, 0, 0], [12.4, 0, 0]],
                              upper=[[6.2, 0, 0], [12.4, 0, 0], [18.71, 0, 0]])
    text = _regions_text(profile, ReportOptions(), SimpleNamespace(length_unit="mm"))
    assert text == "3 equal regions along x: start 0 to 6.2, centre 6.2 to 12.4, end 12.4 to 18.71 mm"


def test_the_input_table_speaks_words_not_python(tmp_path):
    """Row names in words, files one per line, indices without brackets, nothing given as
    'not given'; the JSON keeps its keys."""
    from bedstruct.report._render import _input_html
    assert _input_html(["/a/b.dump", "/a/c.dump"]) == "/a/b.dump<br>/a/c.dump"
    assert _input_html([0, 2]) == "0, 2" and _input_html(None) == "not given"
    path = tmp_path / "bed.dump"
    bedstruct.write_dump(path, [bedstruct.Frame([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]], [0.5, 0.4],
                                                box=[2, 1, 1]).with_units("si")])
    with _only("summary"):
        assert main(["report", str(path), "--no-3d", "--out", str(tmp_path / "r")]) == 0
    page = (tmp_path / "r" / "report.html").read_text()
    assert f"<tr><th>files</th><td>{path}</td></tr>" in page
    assert "<th>frames selected (index in the input)</th><td>0</td>" in page
    assert "[" + str(path) not in page
    doc = json.loads((tmp_path / "r" / "report.json").read_text())
    assert doc["inputs"]["paths"] == [str(path)] and doc["inputs"]["frames_selected"] == [0]
