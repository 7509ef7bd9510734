"""What a multi-layer spreading run printed: the records its deck writes into the log.

The decks of :func:`~bedstruct.dem.backends.spread_layers_deck` print one marker line
per layer, ``MARKER layer=K key=value ...``: the steps waited for flying powder to land
(:func:`landing_offsets`) and the load of the powder on the tool averaged over the
stroke (:func:`tool_loads`), and, as their last command, that the run got to its end
(:func:`run_finished`). The markers are defined here, beside their readers.
"""

from __future__ import annotations

__all__ = ["landing_offsets", "run_finished", "tool_loads"]

_OFFSET_LINE = "BEDSTRUCT_OFFSET"
_LOAD_LINE = "BEDSTRUCT_TOOL_FORCE"
_DONE_LINE = "BEDSTRUCT_DONE"


def _log_records(log_path, marker: str, keys) -> dict:
    """``{layer: {key: value}}`` of the ``MARKER layer=K key=value ...`` lines a deck printed
    (the last line of a layer wins; a line with another set of keys is not one of them)."""
    import re
    num = r"([-+0-9.eEnaNinf]+)"
    pat = re.compile(rf"^{marker} layer=(\d+)" + "".join(f" {k}={num}" for k in keys) + r"\s*$")
    found = {}
    with open(log_path, errors="replace") as fh:
        for line in fh:
            m = pat.match(line.strip())
            if m:
                found[int(m.group(1))] = {k: float(m.group(i + 2)) for i, k in enumerate(keys)}
    return found


def landing_offsets(log_path, n_layers: int) -> tuple:
    """Steps waited for flying powder to land before each layer's tool motion, in all.

    Reads the ``BEDSTRUCT_OFFSET layer=K steps=N`` lines that
    :func:`spread_layers_deck` prints into the engine's log.

    Parameters
    ----------
    log_path : str or os.PathLike
    n_layers : int

    Returns
    -------
    tuple of int
        One cumulative offset per layer (add it to the layer's planned steps).

    Raises
    ------
    ValueError
        When a layer's line is missing (the run stopped early, or the deck was
        not written by :func:`spread_layers_deck`).
    """
    found = {k: int(round(v["steps"])) for k, v in _log_records(log_path, _OFFSET_LINE,
                                                                ("steps",)).items()}
    missing = [k + 1 for k in range(n_layers) if k + 1 not in found]
    if missing:
        raise ValueError(f"{log_path}: no '{_OFFSET_LINE} layer=K steps=N' line for layer(s) "
                         f"{missing}; the run did not reach their tool motion")
    return tuple(found[k + 1] for k in range(n_layers))


def tool_loads(log_path, n_layers: int) -> tuple:
    """Load of the powder on the tool averaged over each layer's stroke (N), from the log.

    The decks of :func:`spread_layers_deck` print ``BEDSTRUCT_TOOL_FORCE layer=K
    fx=.. fy=.. fz=..`` after each stroke: the force of the particles on the tool
    averaged over the stroke's steps by ``fix ave/time ... ave running`` (LIGGGHTS: the
    tool is a ``mesh/surface/stress``; LAMMPS: the per-atom forces of the tool's
    ``wall/gran/region ... contacts``, summed and negated).

    Returns
    -------
    tuple of (3,) tuple of float
        One per layer; NaN where the log has no line for it.
    """
    found = {k: (v["fx"], v["fy"], v["fz"])
             for k, v in _log_records(log_path, _LOAD_LINE, ("fx", "fy", "fz")).items()}
    nan = (float("nan"),) * 3
    return tuple(found.get(k + 1, nan) for k in range(n_layers))


def run_finished(log_path, n_layers: int) -> bool:
    """Whether the run of a :func:`spread_layers_deck` deck of ``n_layers`` layers got to its end.

    The deck's last command prints ``BEDSTRUCT_DONE layer=K`` (K = ``n_layers``) after
    the dumps of the last layer are closed, so a log holding it belongs to a run that
    finished every layer and left every dump complete; a killed, failed or timed-out
    run, or a missing log, gives False.
    """
    try:
        return n_layers in _log_records(log_path, _DONE_LINE, ())
    except FileNotFoundError:
        return False
