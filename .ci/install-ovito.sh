#!/usr/bin/env bash
# Install OVITO (PyPI `ovito>=3.10`, the project's `bench` extra; a ~116 MB wheel) into the
# venv: the independent reader that tests/io/test_io_vs_ovito.py cross-checks bedstruct's
# dump and data-file readers against, and the anchor of benchmarks/bench_read.py.
# Optional and idempotent; never fails the caller: without OVITO those tests skip with a
# reason. Called by .ci/install-engines.sh. Usage: bash .ci/install-ovito.sh [python-of-the-venv]
set -u
PY="${1:-}"
if [ -z "$PY" ]; then
  if [ -x "$(dirname "$0")/../.venv/bin/python" ]; then PY="$(dirname "$0")/../.venv/bin/python"
  else PY="$(command -v python3 || true)"; fi
fi
msg() { echo "[install-ovito] $*"; }

if [ -z "$PY" ]; then
  msg "WARNING: no python found: OVITO not installed (OVITO tests will skip)"
  exit 0
fi
version() { "$PY" -c "import ovito; print('.'.join(map(str, ovito.version)))" 2>/dev/null; }
if v="$(version)" && [ -n "$v" ]; then
  msg "ovito $v already installed in $("$PY" -c 'import sys; print(sys.prefix)')"
  exit 0
fi
log="$(mktemp)"
if "$PY" -m pip install -q "ovito>=3.10" >"$log" 2>&1 && v="$(version)" && [ -n "$v" ]; then
  msg "installed ovito $v (pip install 'ovito>=3.10')"
else
  msg "WARNING: 'pip install ovito>=3.10' failed (OVITO tests will skip): $(tail -n 1 "$log")"
fi
rm -f "$log"
exit 0
