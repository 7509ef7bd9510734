"""Helpers and fixtures for the io tests: small hand-written dump files.

Kept out of a ``conftest.py`` on purpose: several ``conftest`` modules in one
tree shadow each other for ``from conftest import ...``. Test modules import
the fixtures from here.
"""

from __future__ import annotations

import pathlib

import pytest

HEADER = """ITEM: TIMESTEP
{step}
ITEM: NUMBER OF ATOMS
{n}
ITEM: BOX BOUNDS {flags}
0 10
0 10
0 10
ITEM: ATOMS {cols}
"""


def dump_text(rows, *, step=0, cols="id type x y z radius", flags="pp pp pp", n=None) -> str:
    """One frame of a text dump; ``rows`` are strings (one per atom)."""
    head = HEADER.format(step=step, n=len(rows) if n is None else n, flags=flags, cols=cols)
    return head + "".join(r + "\n" for r in rows)


GOOD_ROWS = ["2 1 1.0 2.0 3.0 0.5", "1 2 4.0 5.0 6.0 0.25", "3 1 7.5 8.5 9.5 0.5"]


@pytest.fixture(name="dump_text")
def _dump_text_fixture():
    """The :func:`dump_text` helper (fixtures avoid importing this conftest by name)."""
    return dump_text


@pytest.fixture
def good_rows():
    """Three valid atom rows for ``id type x y z radius``."""
    return list(GOOD_ROWS)


@pytest.fixture
def write(tmp_path):
    """``write(name, text_or_bytes) -> path`` in a temporary folder."""
    def _write(name, content) -> pathlib.Path:
        p = tmp_path / name
        p.write_bytes(content if isinstance(content, bytes) else content.encode())
        return p
    return _write
