"""What the report trusts of its input: contact files, frame selections, sizes, files, units."""

import contextlib
import json

import numpy as np
import pytest

import bedstruct
from bedstruct.cli import main
from bedstruct.core import Contacts, Provenance
from bedstruct.report import build_report
from bedstruct.report import build as build_mod
from bedstruct.report import _picture


def _no_picture(frame, **kw):
    return None, "3-D view not drawn (left out in the tests)"


@pytest.fixture(autouse=True)
def _no_3d_render(monkeypatch):
    monkeypatch.setattr(_picture, "render_3d", _no_picture)


@contextlib.contextmanager
def _only(*keys):
    """Reports built inside run only the named sections (the input is judged as always)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(build_mod, "SECTIONS", [s for s in build_mod.SECTIONS if s[0] in keys])
        yield


def _lattice(spacing, n=(6, 6, 6), radius=0.5):
    """A simple-cubic lattice in a periodic box (si units), and its nearest-neighbour pairs."""
    g = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1).reshape(-1, 3)
    pos = (g + 0.5) * spacing
    box = bedstruct.Box([0, 0, 0], np.asarray(n) * spacing, boundary="pp pp pp")
    frame = bedstruct.Frame(pos, np.full(len(pos), radius), box=box)
    index = {tuple(p): k for k, p in enumerate(g)}
    i, j = [], []
    for k, p in enumerate(g):
        for ax in range(3):
            q = list(p)
            q[ax] = (q[ax] + 1) % n[ax]   # the neighbour across the periodic boundary too
            i.append(k)
            j.append(index[tuple(q)])
    i, j = np.array(i), np.array(j)
    branch = box.minimum_image(pos[j] - pos[i])
    contacts = Contacts(i=i, j=j, branch=branch, radii_i=frame.radii[i], radii_j=frame.radii[j],
                        n_particles=len(pos), source="pairs.local")
    return frame, contacts


def test_contacts_that_do_not_touch_are_flagged_and_not_used():
    frame, pairs = _lattice(spacing=1.122)          # neighbours 1.122 d apart, as a neighbour list
    check = build_mod.contact_gaps(frame, pairs)
    assert check["apart"] and check["n_apart"] == check["n_contacts"] == 3 * 216
    assert check["median_distance_over_radii_sum"] == pytest.approx(1.122)
    with _only("summary", "coordination", "fabric"):
        rep = build_report(frame, contacts=pairs)
    warning = " ".join(rep.inputs["warnings"])
    assert "pairs.local" in warning and "apart" in warning
    assert "Warning:" in rep.section("summary").text
    for key in ("coordination", "fabric"):
        sec = rep.section(key)
        assert sec.status == "not meaningful" and "pairs.local" in sec.text and not sec.numbers
    # the input is judged from geometric contacts: no contact touches in this lattice
    assert rep.state["evidence"]["mean_coordination"].value == 0


def test_touching_contacts_are_trusted_across_the_periodic_boundary():
    frame, pairs = _lattice(spacing=1.0)            # every pair touches, a sixth across the box
    check = build_mod.contact_gaps(frame, pairs)
    assert check["n_apart"] == 0 and not check["apart"]
    with _only("summary", "coordination"):
        rep = build_report(frame, contacts=pairs)
    assert "warnings" not in rep.inputs
    assert rep.section("coordination").numbers["mean"].value == pytest.approx(6.0)


def _with_far_pairs(frame, pairs, share):
    """``pairs`` plus pairs of particles two spacings apart, ``share`` of the whole."""
    m = int(round(share * pairs.n_contacts / (1 - share)))
    i = np.concatenate([pairs.i, pairs.i[:m]])
    rows = np.arange(m)     # row 3 k + axis joins particle k to its neighbour along that axis
    j = np.concatenate([pairs.j, pairs.j[3 * pairs.j[rows] + rows % 3]])   # the next one along
    branch = frame.box.minimum_image(frame.positions[j] - frame.positions[i])
    return Contacts(i=i, j=j, branch=branch, radii_i=frame.radii[i], radii_j=frame.radii[j],
                    n_particles=frame.n_particles, source="mixed.local")


def test_the_share_of_contacts_apart_decides():
    # more than 5 % of the pairs apart by more than 1 % of their radii sum
    assert build_mod.CONTACT_APART_SHARE == 0.05 and build_mod.CONTACT_GAP_TOLERANCE == 0.01
    frame, pairs = _lattice(spacing=1.0)
    few = build_mod.contact_gaps(frame, _with_far_pairs(frame, pairs, 0.04))
    assert 0.03 < few["share_apart"] < 0.05 and not few["apart"]
    many = build_mod.contact_gaps(frame, _with_far_pairs(frame, pairs, 0.07))
    assert 0.06 < many["share_apart"] < 0.08 and many["apart"]
    # a gap within 1 % of the radii sum is a contact (a simulator's skin distance)
    near, near_pairs = _lattice(spacing=1.009)
    assert build_mod.contact_gaps(near, near_pairs)["n_apart"] == 0


def test_the_report_says_which_frame_it_describes():
    frame, _ = _lattice(spacing=1.0)
    early = bedstruct.Frame(frame.positions, frame.radii, box=frame.box, timestep=100)
    late = bedstruct.Frame(frame.positions, frame.radii, box=frame.box, timestep=500)
    with _only("summary"):
        rep = build_report([early, late], frame_indices=[3, 7])
    sec = rep.section("summary")
    assert "n_frames_analysed" not in sec.numbers
    assert sec.numbers["n_frames_selected"].value == 2
    assert sec.numbers["frame_index"].value == 7 and sec.numbers["timestep"].value == 500
    assert "timestep 500" in sec.text and "only" in sec.text
    assert "timestep 500" in rep.inputs["frame_described"]


def test_monodisperse_sizes_are_not_reported_as_a_distribution():
    frame, _ = _lattice(spacing=1.0e-4, radius=25e-6)
    frame = bedstruct.Frame(frame.positions, frame.radii, box=frame.box).with_units("si")
    with _only("psd"):
        sec = build_report(frame).section("psd")
    assert sec.status == "not meaningful"
    assert "monodisperse" in sec.text and "25 µm" in sec.text
    assert not sec.numbers and not sec.tables
    # a spread of sizes keeps the section
    radii = frame.radii * np.linspace(0.9, 1.1, frame.n_particles)
    mixed = bedstruct.Frame(frame.positions, radii, box=frame.box).with_units("si")
    with _only("psd"):
        assert build_report(mixed).section("psd").status == "ok"


def _dump(path, timestep, n, hi=10.0, units=None):
    g = np.stack(np.meshgrid(*[np.arange(2)] * 3, indexing="ij"), -1).reshape(-1, 3)[:n]
    frame = bedstruct.Frame(g * 2.0 + 1.0, np.full(len(g), 1.0), box=bedstruct.Box([0, 0, 0], [hi] * 3),
                            timestep=timestep)
    bedstruct.write_dump(path, [frame])
    if units:   # a LIGGGHTS dump states none; a LAMMPS one may
        text = path.read_text().replace("ITEM: NUMBER OF ATOMS", f"ITEM: UNITS\n{units}\nITEM: NUMBER OF ATOMS")
        path.write_text(text)
    return path


def _cli(args, capsys):
    with _only("summary"):
        code = main(["report", *map(str, args), "--no-3d"])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_files_that_do_not_follow_one_another_are_warned_about(tmp_path, capsys):
    a = _dump(tmp_path / "a.dump", 800, 8)
    b = _dump(tmp_path / "b.dump", 0, 4, hi=12.0)
    code, _, err = _cli([a, b, "--out", tmp_path / "r"], capsys)
    assert code == 0
    line = next(ln for ln in err.splitlines() if "does not continue" in ln)
    assert line.startswith("bedstruct report: warning:") and "b.dump" in line and "a.dump" in line
    assert "timestep (0)" in line and "from 8 to 4" in line and "box changes" in line
    inputs = json.loads((tmp_path / "r" / "report.json").read_text())["inputs"]
    assert any("does not continue" in w for w in inputs["warnings"])
    # files of one run, in order: quiet
    c = _dump(tmp_path / "c.dump", 900, 8)
    code, _, err = _cli([a, c, "--out", tmp_path / "s"], capsys)
    assert code == 0 and "does not continue" not in err


def test_an_empty_frame_is_an_error_naming_its_file():
    empty = bedstruct.Frame(np.zeros((0, 3)), np.zeros(0), box=bedstruct.Box([0, 0, 0], [1, 1, 1]),
                            timestep=7, provenance=Provenance(source="run/empty.dump"))
    with pytest.raises(ValueError, match=r"run/empty\.dump.*timestep 7"):
        build_report(empty)


def test_unknown_units_are_said_once_and_in_the_inputs(tmp_path, capsys):
    plain = _dump(tmp_path / "plain.dump", 0, 8)
    code, _, err = _cli([plain, "--out", tmp_path / "r"], capsys)
    assert code == 0
    notes = [ln for ln in err.splitlines() if "units not stated" in ln]
    assert len(notes) == 1 and "plain.dump" in notes[0] and "--units STYLE" in notes[0]
    inputs = json.loads((tmp_path / "r" / "report.json").read_text())["inputs"]
    assert inputs["units"].startswith("units not stated in") and "plain.dump" in inputs["units"]
    # stated in the file, or given: quiet
    stated = _dump(tmp_path / "stated.dump", 0, 8, units="si")
    for args in ([stated], [plain, "--units", "si"]):
        code, _, err = _cli([*args, "--out", tmp_path / "s"], capsys)
        assert code == 0 and "units not stated" not in err
        assert json.loads((tmp_path / "s" / "report.json").read_text())["inputs"]["units"] == "si"
