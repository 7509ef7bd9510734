"""Usage: python docs/scripts/example_layers_twin.py OUT

Makes the "real" data of the worked example "a layer-by-layer packing experiment"
(docs/diagnose.md): LIGGGHTS 3.8 runs, at the tiny scale model, of the design below with
non-sphericity at 0.2 (rolling friction 0.05 + 0.2, EPSD2), an effect the diagnosis is not
told. Three
repetitions of the experiment (seeds 4501, 4501 + 7919, 4501 + 2 x 7919), each reading with
Gaussian reading noise of the design's stated uncertainty, written by the blind benchmark's
twin code (bedstruct.diagnose.validation.blind_twins.twin_measurements) as OUT/example-layers.toml;
data/measurements/example-layers.toml is that file. OUT/design.toml is the design (its values
are placeholders; the twin replaces them). About 15 CPU-minutes on one core.
"""
import sys
from pathlib import Path

from bedstruct.diagnose import load_measurements
from bedstruct.diagnose.validation.blind_twins import TwinSpec, twin_measurements

DESIGN = '''
[meta]
title = "Layer-by-layer packing experiment: six 300 um layers between side walls 0.8 mm apart"
notes = """A LIGGGHTS 3.8 twin at the tiny scale model (bedstruct's scale-model preset: every \
diameter of the stated PSD doubled, soft particles), not a laboratory measurement. Values are \
the means of three repetitions of the experiment, each read with Gaussian reading noise of the \
reading uncertainty named in the observable's note; the stated uncertainty is \
sqrt(reading^2 + s^2 / 3), s the standard deviation of the three readings (the run-to-run \
scatter of the process). Values in SI: packing fraction 1, bed height m, angle deg."""

[conditions]
psd = {d10 = "43.71 um", d50 = "56.09 um", d90 = "69.27 um", d_min = "36 um", d_max = "80 um", \
diameters = ["36 um", "42 um", "48 um", "54 um", "60 um", "66 um", "72 um", "80 um"], \
cumulative = [0.0, 0.06, 0.2, 0.42, 0.65, 0.84, 0.95, 1.0]}
layers = 6
layer_thickness = "300 um"
blade_speed = "2.54 cm/s"
platform_length = "3 mm"
platform_width = "0.8 mm"
side_walls = true
wall_distance = "0.8 mm"

[[observable]]
name = "static_angle"
kind = "static_angle"
unit = "deg"
value = 35.0
uncertainty = 1.0
role = "calibrate"
note = "Angle of repose of a pile drained between the side walls, both flanks fitted; reading uncertainty 1 deg."
'''

PF_NOTE = ("Packing fraction of the bed's centre third after layer {k} (solid volume in the "
           "region over the region's volume up to the bed's top); reading uncertainty 0.01.")
BH_NOTE = ("Mean height of the bed's top surface above the platform after layer {k}; reading "
           "uncertainty 10 um (profilometer).")
PF_HELD_OUT = (4, 6)
BH_HELD_OUT = (2, 4, 6)


def design_text() -> str:
    text = DESIGN
    for k in range(1, 7):
        text += f'''
[[observable]]
name = "packing_fraction_layer{k}"
kind = "packing_fraction"
unit = "1"
value = 0.5
uncertainty = 0.01
role = "{'validate' if k in PF_HELD_OUT else 'calibrate'}"
note = "{PF_NOTE.format(k=k)}"
[observable.conditions]
layer = {k}
region = "center"
'''
    for k in range(1, 7):
        text += f'''
[[observable]]
name = "bed_height_layer{k}"
kind = "bed_height"
unit = "um"
value = {300.0 * k}
uncertainty = 10.0
role = "{'validate' if k in BH_HELD_OUT else 'calibrate'}"
note = "{BH_NOTE.format(k=k)}"
[observable.conditions]
layer = {k}
'''
    return text


def main(out) -> Path:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "design.toml").write_text(design_text(), encoding="utf-8")
    design = load_measurements(out / "design.toml")
    spec = TwinSpec("example-layers", "effect", "non_sphericity", 0.2, 1.0, 4501)
    return twin_measurements(spec, "liggghts", design, out / "example-layers.toml", preset="tiny",
                             repeats=3, title=design.title,
                             source="LIGGGHTS 3.8 twin (docs/scripts/example_layers_twin.py)")


if __name__ == "__main__":
    print(main(sys.argv[1]))
