"""``bedstruct diagnose --json``: the last line is the compact answer, without float noise."""

import json
import pathlib
import re

from bedstruct.cli import main

SEED = pathlib.Path(__file__).resolve().parents[2] / "data" / "measurements" / "seed.toml"


def _significant_digits(v: float) -> int:
    mantissa = f"{v!r}".lower().split("e")[0].lstrip("-").replace(".", "").lstrip("0")
    return len(mantissa.rstrip("0")) if "." in f"{v!r}" else len(mantissa)


def test_json_last_line_is_the_compact_answer(tmp_path, capsys):
    assert main(["diagnose", "--sim", "surrogate", "--real", str(SEED), "--out", str(tmp_path),
                 "--json"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    j = json.loads(out[-1])
    assert {"verdict", "effect", "magnitude", "shrink", "where"} <= set(j)
    assert j["verdict"] == "attributed" and j["effect"] == "missing_fines"
    mag = j["magnitude"]
    lo, hi = mag["interval"]
    assert mag["name"] == "fines_mass_fraction" and lo < mag["value"] < hi
    assert set(j["shrink"]) >= {"value", "interval"} and len(j["shrink"]["interval"]) == 2
    assert [w["observable"] for w in j["where"]][:1] == ["psd_before"] and len(j["where"]) == 3
    assert all(set(w) >= {"measured", "simulated", "unit", "z"} for w in j["where"])
    # no float noise: every number carries at most six significant digits
    numbers = [float(x) for x in re.findall(r"(?<![\w.])-?\d+\.\d+(?:e-?\d+)?", out[-1])]
    assert numbers and all(_significant_digits(v) <= 6 for v in numbers), numbers
    # the full answer and the report are in the folder
    assert (tmp_path / "diagnosis.json").is_file() and (tmp_path / "report.html").is_file()


def _help(capsys, *argv) -> str:
    import pytest
    with pytest.raises(SystemExit) as exc:
        main(["diagnose", *argv, "--help"])
    assert exc.value.code == 0
    return capsys.readouterr().out


def _options(text: str) -> set[str]:
    return set(re.findall(r"^  (--[a-z-]+)", text[text.index("options:"):], re.MULTILINE))


_VALIDATE = {"--preset", "--simulator", "--twin-seed", "--campaign", "--records", "--records-only",
             "--shard", "--twin-jobs", "--twin-repeats"}
_BENCHMARK = {"--twins-engine", "--n", "--draw", "--diagnose-setting", "--score", "--rediagnose"}


def test_each_mode_s_help_lists_its_own_options_only(capsys):
    plain = _help(capsys)
    assert len(plain.splitlines()) <= 45, len(plain.splitlines())
    assert "docs/diagnose.md" in plain
    shown = _options(plain)
    assert {"--sim", "--real", "--out", "--library", "--workers", "--scheduler", "--seed",
            "--json", "--progress", "--refine", "--top-up"} <= shown
    assert not shown & (_VALIDATE | _BENCHMARK), shown & (_VALIDATE | _BENCHMARK)
    validate = _help(capsys, "validate")
    shown = _options(validate)
    assert _VALIDATE <= shown and "--seed" in shown and "--refine" in shown
    assert not shown & (_BENCHMARK | {"--real", "--library", "--workers", "--scheduler", "--np"})
    assert validate.startswith("usage: bedstruct diagnose validate")
    bench = _help(capsys, "benchmark")
    shown = _options(bench)
    assert _BENCHMARK - {"--diagnose-setting"} <= shown and "--diagnose-setting" not in shown
    assert {"--out", "--seed", "--sim", "--library"} <= shown
    assert not shown & ((_VALIDATE - {"--preset"}) | {"--real", "--np", "--jobs", "--refine"})
    assert len({plain, validate, bench}) == 3


def test_options_stay_where_they_were_accepted():
    """Options before or after the mode's name reach it; an option of another mode is
    parsed (and then refused by the run with the reason, not by an unknown-option error)."""
    from bedstruct.cli import build_parser
    parser = build_parser()
    a = parser.parse_args(["diagnose", "--preset", "tiny", "validate", "--seed", "1", "--json"])
    assert (a.action, a.preset, a.seed, a.json, a.twin_seed, a.real) == \
        ("validate", "tiny", 1, True, None, None)
    a = parser.parse_args(["diagnose", "--seed", "2", "validate"])
    assert (a.action, a.seed) == ("validate", 2)
    a = parser.parse_args(["diagnose", "benchmark", "--score", "x", "y", "--json"])
    assert (a.action, a.score, a.n, a.diagnose_setting, a.progress) == \
        ("benchmark", ["x", "y"], None, None, False)
    a = parser.parse_args(["diagnose", "--sim", "s", "--real", "r", "--out", "o", "--twin-seed", "3"])
    assert (a.action, a.twin_seed) == (None, 3)
    a = parser.parse_args(["diagnose", "validate", "--real", "r", "--np", "2"])
    assert (a.real, a.np) == ("r", 2)


def test_option_values_out_of_range_are_refused_by_the_parser(capsys, tmp_path):
    import pytest
    for argv, message in [
            (["--sim", "surrogate", "--real", str(SEED), "--out", str(tmp_path), "--seed", "-3"],
             "argument --seed: expected a whole number >= 0; got '-3'"),
            (["validate", "--seed", "-3"], "argument --seed: expected a whole number >= 0"),
            (["validate", "--twin-seed", "-1"], "argument --twin-seed: expected a whole number >= 0"),
            (["benchmark", "--seed", "x"], "argument --seed: expected a whole number >= 0; got 'x'"),
            (["benchmark", "--n", "2", "--out", str(tmp_path)], "argument --n: expected a whole number >= 4"),
            (["--sim", "surrogate", "--real", str(SEED), "--out", str(tmp_path), "--library",
              str(tmp_path / "lib"), "--workers", "0"], "argument --workers: expected a whole number >= 1"),
            (["validate", "--twin-jobs", "0"], "argument --twin-jobs: expected a whole number >= 1"),
            (["--sim", "surrogate", "--real", str(SEED), "--out", str(tmp_path), "--np", "0"],
             "argument --np: expected a whole number >= 1")]:
        with pytest.raises(SystemExit) as exc:
            main(["diagnose", *argv])
        assert exc.value.code == 2, argv
        assert message in capsys.readouterr().err, argv
    assert not (tmp_path / "report.html").exists()
