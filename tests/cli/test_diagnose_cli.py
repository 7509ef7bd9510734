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
