"""The notebooks run clean, top to bottom, on the bundled small data."""

import importlib.util
import pathlib

import pytest

NOTEBOOKS = sorted((pathlib.Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path):
    if importlib.util.find_spec("nbclient") is None or importlib.util.find_spec("ipykernel") is None:
        pytest.skip("nbclient/ipykernel not installed (pip install -e '.[dev]')")
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}})
    client.execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    errors = [o for o in outputs if o.get("output_type") == "error"]
    assert not errors
    # what a reader sees: no warnings (printed on stderr) and numbers, not numpy reprs
    warned = [o["text"] for o in outputs if o.get("output_type") == "stream"
              and (o.get("name") == "stderr" or "Warning" in o["text"])]
    assert not warned, warned
    texts = [o["text"] if o.get("output_type") == "stream" else o.get("data", {}).get("text/plain", "")
             for o in outputs]
    reprs = [t for t in texts if "np.float64(" in t or "np.int64(" in t]
    assert not reprs, reprs
