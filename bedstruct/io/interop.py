"""Exchange with MDAnalysis and PyVista.

MDAnalysis stores positions and box lengths as float32, has no box origin and
no unit style of its own; :func:`to_universe` therefore also keeps the exact box
(``lo``, ``hi``, ``tilt``, boundary flags), the timestep, the time, the unit
style, angular velocities, image flags and extra columns in
``universe.trajectory.ts.data`` so that :func:`from_universe` restores them;
positions come back rounded to float32.
"""

from __future__ import annotations

import numpy as np

from ..core import Box, Contacts, Frame, Provenance, Units

__all__ = ["to_universe", "from_universe", "to_pyvista"]


def to_universe(frame: Frame):
    """An MDAnalysis ``Universe`` holding one frame.

    Atoms get ``ids``, ``types`` (as strings, MDAnalysis convention) and
    ``radii``; velocities and forces are set when the frame has them. The box
    becomes ``dimensions`` (lengths and angles).

    Parameters
    ----------
    frame : Frame
        The particles (N >= 1).

    Returns
    -------
    MDAnalysis.Universe

    Examples
    --------
    >>> from bedstruct import Frame, to_universe
    >>> u = to_universe(Frame([[1.0, 2.0, 3.0]], [0.5], box=[4, 4, 4]))
    >>> u.atoms.positions.tolist(), u.dimensions.tolist()
    ([[1.0, 2.0, 3.0]], [4.0, 4.0, 4.0, 90.0, 90.0, 90.0])
    """
    try:
        import MDAnalysis as mda
        from MDAnalysis.lib.mdamath import triclinic_box
    except ImportError:  # pragma: no cover - dependency
        raise ImportError("to_universe needs MDAnalysis (pip install MDAnalysis)") from None
    if not isinstance(frame, Frame):
        raise TypeError(f"expected a Frame; got {type(frame).__name__}")
    n = frame.n_particles
    if n == 0:
        raise ValueError("MDAnalysis cannot hold a frame with 0 particles")
    u = mda.Universe.empty(n, trajectory=True, velocities=frame.velocities is not None,
                           forces=frame.forces is not None)
    u.add_TopologyAttr("ids", frame.ids)
    u.add_TopologyAttr("types", frame.types.astype(str))
    u.add_TopologyAttr("radii", frame.radii)
    u.atoms.positions = frame.positions
    if frame.velocities is not None:
        u.atoms.velocities = frame.velocities
    if frame.forces is not None:
        u.atoms.forces = frame.forces
    m = frame.box.matrix
    u.dimensions = triclinic_box(m[:, 0], m[:, 1], m[:, 2])
    ts = u.trajectory.ts
    ts.data["step"] = frame.timestep
    ts.data["bedstruct_box"] = {"lo": frame.box.lo.copy(), "hi": frame.box.hi.copy(),
                                "tilt": frame.box.tilt.copy(), "boundary": frame.box.boundary}
    ts.data["bedstruct_frame"] = {
        "n_atoms": n, "units": frame.units, "time": frame.time,
        "omegas": None if frame.omegas is None else frame.omegas.copy(),
        "images": None if frame.images is None else frame.images.copy(),
        "columns": {k: v.copy() for k, v in frame.columns.items()}}
    return u


def from_universe(universe, *, radius=None, boundary=None) -> Frame:
    """A :class:`Frame` from the current time step of an MDAnalysis universe.

    Parameters
    ----------
    universe : MDAnalysis.Universe or AtomGroup
        The particles; ``radii`` are used when set (non-zero).
    radius : float, optional
        Radius for every particle when the universe has no radii.
    boundary : str, optional
        Boundary flags (default: those stored by :func:`to_universe`, else
        ``"pp pp pp"``).

    Returns
    -------
    Frame
        Positions in float64 (from MDAnalysis' float32), rows sorted by id.

    Examples
    --------
    >>> from bedstruct import Frame, from_universe, to_universe
    >>> u = to_universe(Frame([[1.0, 2.0, 3.0]], [0.5], box=[4, 4, 4], timestep=7))
    >>> f = from_universe(u)
    >>> f.timestep, f.positions.tolist(), f.radii.tolist()
    (7, [[1.0, 2.0, 3.0]], [0.5])

    .. versionadded:: 0.1
    """
    if not hasattr(universe, "atoms") or not hasattr(universe.atoms, "universe"):
        raise TypeError(f"expected an MDAnalysis Universe or AtomGroup; got "
                        f"{type(universe).__name__}")
    atoms = universe.atoms
    u = atoms.universe
    ts = u.trajectory.ts
    n = len(atoms)
    notes = []
    extra = ts.data.get("bedstruct_frame")
    if extra is not None and extra.get("n_atoms") != u.atoms.n_atoms:
        extra = None
    radii = None
    if hasattr(atoms, "radii"):
        r = np.asarray(atoms.radii, dtype=np.float64)
        if np.all(r > 0):
            radii = r
    if radii is None:
        if radius is None:
            raise ValueError("the universe has no (positive) radii; pass radius=")
        radii = np.full(n, float(radius))
        notes.append(f"radius {float(radius)!r} given by the caller")
    stored = ts.data.get("bedstruct_box")
    if stored is not None:
        box = Box(stored["lo"], stored["hi"], stored["tilt"],
                  boundary if boundary is not None else stored["boundary"])
    else:
        if ts.dimensions is None:
            raise ValueError("the universe has no box dimensions")
        from MDAnalysis.lib.mdamath import triclinic_vectors
        v = triclinic_vectors(ts.dimensions).astype(np.float64)
        box = Box(np.zeros(3), [v[0, 0], v[1, 1], v[2, 2]], [v[1, 0], v[2, 0], v[2, 1]],
                  boundary or "pp pp pp")
        notes.append("box from MDAnalysis dimensions (origin at 0)")
    try:
        names = np.asarray(atoms.types)
    except (AttributeError, ValueError):  # MDAnalysis' NoDataError is both
        names = None
        types = np.ones(n, dtype=np.int64)
        notes.append("the universe has no atom types: all 1")
    try:
        if names is not None:
            types = names.astype(np.int64)
    except (ValueError, TypeError):
        uniq, inv = np.unique(names, return_inverse=True)
        types = inv + 1
        notes.append("non-numeric MDAnalysis types mapped to 1..k: " + " ".join(map(str, uniq)))
    try:
        ids = np.asarray(atoms.ids)
    except (AttributeError, ValueError):  # MDAnalysis' NoDataError is both
        ids = np.asarray(atoms.indices) + 1
        notes.append("the universe has no atom ids: ids are the atom indices + 1")
    kw = {}
    if ts.has_velocities:
        kw["velocities"] = atoms.velocities.astype(np.float64)
    if ts.has_forces:
        kw["forces"] = atoms.forces.astype(np.float64)
    if extra is not None:
        rows = np.asarray(atoms.indices)
        units = extra["units"]
        time = extra["time"]
        for name in ("omegas", "images"):
            if extra[name] is not None:
                kw[name] = extra[name][rows]
        kw["columns"] = {k: v[rows] for k, v in extra["columns"].items()}
    else:
        units = Units(None)
        time = None
        notes.append("unit style unknown (MDAnalysis works in angstrom and ps); set it with "
                     "frame.with_units()")
    notes.append("positions from MDAnalysis (float32 precision)")
    frame = Frame(atoms.positions.astype(np.float64), radii, box=box,
                  timestep=int(ts.data.get("step", ts.frame)), ids=ids, types=types,
                  time=time, units=units,
                  provenance=Provenance(source=str(getattr(u, "filename", None) or "MDAnalysis"),
                                        frame_index=int(ts.frame), notes=tuple(notes)), **kw)
    return frame.sorted_by_id()


def to_pyvista(frame: Frame, contacts: Contacts | None = None):
    """PyVista data for 3-D views of a frame (and its contacts).

    Parameters
    ----------
    frame : Frame
        The particles.
    contacts : Contacts, optional
        Contacts of the frame, drawn as lines from particle ``i`` along the
        minimum-image branch vector (so periodic contacts do not span the box).

    Returns
    -------
    pyvista.PolyData or pyvista.MultiBlock
        Points with point data ``radius``, ``id``, ``type`` and every vector
        and column of the frame; with ``contacts``, a MultiBlock of
        ``"particles"`` and ``"contacts"`` (lines with cell data ``overlap``,
        ``periodic``, and forces when known).

    Examples
    --------
    >>> from bedstruct import Frame, to_pyvista
    >>> mesh = to_pyvista(Frame([[0, 0, 0], [1, 0, 0]], [0.5, 0.5], box=[2, 2, 2]))
    >>> mesh.n_points, sorted(mesh.point_data.keys())[:3]
    (2, ['id', 'radius', 'type'])
    """
    try:
        import pyvista as pv
    except ImportError:  # pragma: no cover - dependency
        raise ImportError("to_pyvista needs pyvista (pip install pyvista)") from None
    if not isinstance(frame, Frame):
        raise TypeError(f"expected a Frame; got {type(frame).__name__}")
    pts = pv.PolyData(np.ascontiguousarray(frame.positions))
    pts.point_data["radius"] = frame.radii
    pts.point_data["id"] = frame.ids
    pts.point_data["type"] = frame.types
    for name in ("velocities", "omegas", "forces", "images"):
        arr = getattr(frame, name)
        if arr is not None:
            pts.point_data[name] = arr
    for name, arr in frame.columns.items():
        arr = np.asarray(arr)
        if arr.dtype.kind in "biuf":
            pts.point_data[name] = arr.reshape(arr.shape[0], -1) if arr.ndim > 2 else arr
    if contacts is None:
        return pts
    if contacts.n_particles != frame.n_particles:
        raise ValueError(f"`contacts` index {contacts.n_particles} particles but `frame` has "
                         f"{frame.n_particles}")
    m = contacts.n_contacts
    start = frame.positions[contacts.i]
    ends = start + contacts.branch
    points = np.empty((2 * m, 3))
    points[0::2] = start
    points[1::2] = ends
    lines = np.empty((m, 3), dtype=np.int64)
    lines[:, 0] = 2
    lines[:, 1] = np.arange(0, 2 * m, 2)
    lines[:, 2] = np.arange(1, 2 * m, 2)
    net = pv.PolyData(points, lines=lines.reshape(-1)) if m else pv.PolyData()
    if m:
        net.cell_data["overlap"] = contacts.overlap
        net.cell_data["periodic"] = contacts.periodic.astype(np.uint8)
        if contacts.force is not None:
            net.cell_data["force"] = contacts.force
            net.cell_data["force_normal_magnitude"] = (
                np.linalg.norm(contacts.force_normal, axis=1)
                if contacts.force_normal is not None else np.zeros(m))
    blocks = pv.MultiBlock()
    blocks["particles"] = pts
    blocks["contacts"] = net
    return blocks
