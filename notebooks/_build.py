"""Regenerate the notebooks from their cell sources (keeps them reviewable as code).

Run ``python notebooks/_build.py``; outputs are left empty (CI executes them).
"""

import pathlib

import nbformat as nbf

HERE = pathlib.Path(__file__).parent


def notebook(cells):
    nb = nbf.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    for kind, src in cells:
        nb.cells.append(nbf.v4.new_markdown_cell(src) if kind == "md" else nbf.v4.new_code_cell(src))
    return nb


ANALYSE = [
    ("md", "# Analysing a spread powder bed\n\nThis notebook reads the bundled spread bed (made by "
           "bedstruct's own engine, see `data/samples/README.md`) with its contact dump, and measures "
           "it the way the seed report does: packing fraction along the bed, coordination number and "
           "German's law, size distribution, surface roughness and the fabric of contact normals."),
    ("code", "import pathlib\nimport numpy as np\nimport bedstruct\nfrom bedstruct import analysis, plot\n\n"
             "root = pathlib.Path.cwd()\nwhile not (root / 'data' / 'samples').is_dir():\n    root = root.parent\n"
             "samples = root / 'data' / 'samples' / 'spread'"),
    ("md", "## Read the bed and its contacts\n\nThe dump is in SI units (it does not say so, so we tell "
           "the reader). Contacts come from a LIGGGHTS-style `pair/gran/local` file joined by particle id."),
    ("code", "frame = bedstruct.read_dump(samples / 'bed.dump.gz', units='si')[-1]\n"
             "keywords = ['pos', 'id', 'force', 'force_normal', 'force_tangential', 'contactArea']\n"
             "contacts = bedstruct.read_dump_local(samples / 'contacts.dump.gz', keywords=keywords, frames=frame)[frame.timestep]\n"
             "print(frame)\nprint(contacts)"),
    ("md", "Geometric detection finds the same network from positions and radii alone:"),
    ("code", "geometric = bedstruct.find_contacts(frame)\n"
             "match = analysis.compare_contacts(geometric, contacts)\nmatch"),
    ("md", "## Packing fraction and coordination along the bed"),
    ("code", "print('seed definition (bounding box):', float(bedstruct.packing_fraction(frame).fraction))\n"
             "thirds = analysis.packing_along(frame, 3)\nprint('start/centre/end:', np.round(thirds.fractions, 3))\n"
             "cn = bedstruct.coordination(frame, contacts)\nprint('mean CN', round(cn.mean, 3), 'mechanical', round(cn.mechanical, 3))"),
    ("code", "windows = analysis.packing_along(frame, 12)\n"
             "per_window = analysis.coordination_by_window(frame, windows.lower, windows.upper, result=cn)\n"
             "fit = bedstruct.fit_german_law(windows.fractions, per_window.mean)\n"
             "print(f'a = {fit.a:.3f} {fit.a_ci}, b = {fit.b:.4f} {fit.b_ci}, unfitted deviation {fit.unfitted_deviation:.2f}')\n"
             "fig, _ = plot.plot_german(fit)\nfig"),
    ("md", "## Size distribution and surface"),
    ("code", "psd = analysis.particle_size_distribution(frame, weighting='volume')\n"
             "print('D10/D50/D90 (um):', np.round(np.array([psd.d10, psd.d50, psd.d90]) * 1e6, 1))\n"
             "surface = analysis.surface_height_map(frame)\n"
             "print('Sa, Sq (um):', round(surface.sa * 1e6, 1), round(surface.sq * 1e6, 1))"),
    ("md", "## Fabric of the contact network\n\nKanatani tensors of ranks 2 and 4 per region, and the "
           "rose diagrams of seed figure 22."),
    ("code", "regions = analysis.region_fabric(contacts, frame, n_regions=3)\n"
             "for name, t in zip(['start', 'centre', 'end'], regions.tensors):\n"
             "    print(name, np.round(t.eigenvalues, 3), 'anisotropy', round(t.anisotropy, 3))\n"
             "plot.plot_rose_grid(regions.tensors, names=['start', 'centre', 'end'])"),
    ("code", "expansion = bedstruct.harmonic_expansion(contacts.normals, 8)\n"
             "np.round(expansion.power, 5)"),
]

WORKFLOW = [
    ("md", "# Running and calibrating a workflow\n\nThe seed report's experiments run on bedstruct's "
           "embedded DEM engine from a TOML configuration. Presets state their scaling choices "
           "(softened modulus, coarse-grained sizes, a narrow periodic strip); `tiny` runs in "
           "seconds, `small` in minutes, `seed` is the report's full geometry (hours)."),
    ("code", "import tempfile\nimport numpy as np\nimport bedstruct\nfrom bedstruct import workflows\n\n"
             "cfg = workflows.load_config(preset='tiny')\nprint(cfg['description'])\n"
             "print('contact model:', cfg['contact'])"),
    ("md", "## Angle of repose\n\nA box is half filled by raindrop insertion, the bottom plate slides "
           "out and the pile left on the ledge is measured on both flanks."),
    ("code", "out = tempfile.mkdtemp()\nrepose = workflows.run_repose(cfg, out=out + '/repose')\n"
             "print(f'angle {repose.angle_deg:.1f} +- {repose.angle_std_deg:.1f} deg at cohesion {repose.cohesion:g} J/m^3')"),
    ("md", "Options are overridden like on the command line (`--set key=value`); more friction gives a "
           "steeper pile:"),
    ("code", "rough = workflows.load_config(preset='tiny', overrides=['contact.friction=0.8'])\n"
             "steeper = workflows.run_repose(rough, out=out + '/repose-rough')\n"
             "print(f'friction 0.8: {steeper.angle_deg:.1f} deg')"),
    ("md", "## Calibration\n\n`calibrate_cohesion` brackets the SJKR cohesion energy density that "
           "reproduces a target static angle over replicate runs. Here the evaluation is a stand-in "
           "(a known linear angle-cohesion law) so the notebook stays fast; with `evaluate=None` it "
           "runs the repose workflow at each cohesion."),
    ("code", "law = lambda k: 20.0 + 1e-3 * k\n"
             "cal = workflows.calibrate_cohesion(cfg, target_deg=25.0, bracket=(0.0, 1e4), "
             "evaluate=lambda k: (law(k), 0.5, ()))\n"
             "print(f'calibrated cohesion {cal.cohesion:.0f} +- {cal.cohesion_std:.0f} J/m^3 (converged: {cal.converged})')"),
    ("md", "## Multi-layer spreading\n\nThe pile is generated once and reinserted in front of the "
           "blade before each layer; the platform is lowered by each layer's gap."),
    ("code", "spread = workflows.run_spread(cfg, out=out + '/spread')\n"
             "for layer in spread.layers:\n"
             "    print(layer.index, f'bed height {layer.bed_height_m * 1e6:.0f} um (nominal {layer.nominal_height * 1e6:.0f})', "
             "'packing', layer.packing_fraction)"),
    ("md", "Every layer's bed is a LIGGGHTS dump with its contacts, readable by any analysis or by "
           "`bedstruct report`."),
]

DIAGNOSE = [
    ("md", "# Diagnosing a sim-to-real gap\n\nThe diagnosis compares measurements with simulations, "
           "locates the gap, attributes it to unmodelled effects from a catalogue, and says how far "
           "adding the effect closes it on held-out observables. Here it runs on the seed's "
           "measurements (`data/measurements/seed.toml`) with the analytic *surrogate* simulator, "
           "which stands in for the DEM engine and says so in every output."),
    ("code", "import pathlib\nfrom bedstruct import diagnose\n\nroot = pathlib.Path.cwd()\n"
             "while not (root / 'data' / 'measurements').is_dir():\n    root = root.parent\n"
             "measurements = diagnose.load_measurements(root / 'data' / 'measurements' / 'seed.toml')\n"
             "len(measurements.measurements)"),
    ("md", "The catalogue of effects the diagnosis can attribute a gap to:"),
    ("code", "for effect in diagnose.catalogue():\n    print(f'{effect.name:20s} {effect.unit:10s} prior {effect.prior}')"),
    ("md", "## Where, which, how far\n\nThe diagnosis of the seed's measurements against the "
           "surrogate: the ranked residuals say *where* the gap is, the attribution *which* "
           "effect explains it (with a magnitude and its interval), and the rerun at that "
           "magnitude *how far* it closes the gap on held-out observables, and whether it "
           "confirms the attribution."),
    ("code", "sim = diagnose.SurrogateSimulator(diagnose.diagnosis_design(measurements, diagnose.catalogue()))\n"
             "result = diagnose.diagnose(measurements, sim, base=diagnose.BASE_PARAMETERS, replicates=3)\n"
             "print(result.verdict, '-', result.attribution.reason)\n"
             "for effect in result.attribution.which():\n"
             "    print(effect['effect'], f\"{effect['magnitude']:.3g}\", effect['interval'], effect['unit'])\n"
             "print('rerun fits the calibration observables: p =', round(result.shrink.p_rerun_calibration, 3))"),
    ("code", "from bedstruct.diagnose import figures as plot_diagnose\n"
             "fig, _ = plot_diagnose.plot_where(result.where)\nfig"),
    ("md", "The attributed effect's response against its magnitude, interpolated through the "
           "magnitudes it was simulated at (circles; diamonds are magnitudes simulated during "
           "the fit), with what the data ask of it (dotted). The fitted magnitude and its "
           "interval are the vertical line and band."),
    ("code", "fig, _ = plot_diagnose.plot_effect_response(result)\nfig"),
    ("md", "The interval is read from the profile of chi-square over the magnitude: at each "
           "magnitude the recalibration is refitted, and the interval holds the magnitudes within "
           "3.84 of the lowest chi-square (dashed line). A flat profile would say the data hardly "
           "tell magnitudes apart."),
    ("code", "fig, _ = plot_diagnose.plot_magnitude_profile(result)\nfig"),
    ("md", "Validation on synthetic twins whose effect is withheld (tiny preset, surrogate simulator):"),
    ("code", "result = diagnose.validate(preset='tiny', seed=0)\n"
             "print({k: getattr(result, k) for k in ('top1_accuracy', 'null_false_attribution', "
             "'out_of_catalogue_unexplained', 'median_gap_shrink')})"),
]


def main():
    nbf.write(notebook(ANALYSE), HERE / "01-analyse-spread-bed.ipynb")
    nbf.write(notebook(WORKFLOW), HERE / "02-run-and-calibrate.ipynb")
    nbf.write(notebook(DIAGNOSE), HERE / "03-diagnose-gap.ipynb")


if __name__ == "__main__":
    main()
