"""docs/getting-started.md runs as written: its shell commands and Python blocks, in order."""

from __future__ import annotations

import json
import pathlib
import re
import shlex

import pytest

from bedstruct.cli import main

ROOT = pathlib.Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "getting-started.md"


def _blocks(language):
    return re.findall(rf"```{language}\n(.*?)```", PAGE.read_text(), re.S)


def test_the_page_has_commands_and_python():
    assert len(_blocks("bash")) >= 3 and len(_blocks("python")) >= 3


def test_the_commands_run(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    commands = [line.split("#")[0].strip() for block in _blocks("bash")[1:]
                for line in block.splitlines() if line.startswith("bedstruct ")]
    assert commands, "no bedstruct command on the page"
    for cmd in commands:
        argv = shlex.split(cmd)[1:]
        if "--out" in argv:
            argv[argv.index("--out") + 1] = str(tmp_path / "report")
        assert main(argv) == 0, cmd
        out = capsys.readouterr().out
        if "--json" in argv:
            json.loads(out.strip().splitlines()[-1])
    assert (tmp_path / "report" / "report.html").is_file()


def test_the_python_runs_and_prints_numbers(tmp_path, monkeypatch, capsys):
    pytest.importorskip("matplotlib")
    monkeypatch.chdir(tmp_path)
    namespace = {}
    for block in _blocks("python"):
        exec(compile(block.replace('"data/samples/', f'"{ROOT}/data/samples/'), str(PAGE), "exec"),
             namespace)
    out = capsys.readouterr().out
    assert "3520" in out and "packing along the bed" in out and "D10/D50/D90" in out
    assert (tmp_path / "packing.png").stat().st_size > 1000
