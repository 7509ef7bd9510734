"""Comparing run folders: a resumed run against an uninterrupted one."""

from __future__ import annotations

import gzip
import json


def run_files(root, skip=("run.json", "results.json", "result.json")) -> dict:
    """{relative path: content (decompressed)} of the files of run folder ``root``, without
    the files named in ``skip`` (those that hold paths, times or the run's status)."""
    out = {}
    for f in sorted(root.rglob("*")):
        if f.is_file() and f.name not in skip:
            data = f.read_bytes()
            out[str(f.relative_to(root))] = gzip.decompress(data) if f.suffix == ".gz" else data
    return out


def without_times(d) -> dict:
    """A result dictionary without its wall times (the only numbers a resume may change)."""
    d = json.loads(json.dumps(d))
    d.pop("extra", None)
    for item in list(d.get("replicates", ())) + list(d.get("layers", ())):
        item.pop("wall_time")
    return d
