#!/usr/bin/env bash
# Create .venv/ (Python >= 3.12) at the repository root and install the project with its test
# and documentation dependencies. Idempotent: does nothing when pyproject.toml, setup.py and this
# script have not changed since the last run.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv"
stamp="$venv/.mpfem-bootstrap"
want="$(cat "$root/pyproject.toml" "$root/setup.py" "${BASH_SOURCE[0]}" | sha256sum | cut -c1-16)"
if [[ -x "$venv/bin/python" && -f "$stamp" && "$(cat "$stamp")" == "$want" ]]; then
  exit 0
fi

ok_python() {  # python >= 3.12 ?
  "$1" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 12) else 1)' 2>/dev/null
}
python=""
candidates=("${PYTHON:-}" python3.12 python3.13 python3)
if command -v pyenv >/dev/null 2>&1; then
  for v in $(pyenv versions --bare 2>/dev/null | grep -E '^3\.1[2-9]' || true); do
    candidates+=("$(pyenv prefix "$v")/bin/python3")
  done
fi
candidates+=("$HOME"/.pyenv/versions/3.1[2-9]*/bin/python3)
for c in "${candidates[@]}"; do
  [[ -n "$c" ]] || continue
  if command -v "$c" >/dev/null 2>&1 && ok_python "$c"; then python="$c"; break; fi
done
if [[ -z "$python" ]]; then
  echo "bootstrap: no Python >= 3.12 found (set PYTHON=/path/to/python3.12)" >&2
  exit 1
fi

echo "bootstrap: creating $venv with $("$python" --version) ($python)"
rm -rf "$venv"
"$python" -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --upgrade pip
"$venv/bin/python" -m pip install --quiet -e "$root[test,docs]"
# DOLFINx's compiled module needs libmpi.so.12 (in .venv/lib), which only mpi4py knows how to
# find: a user script importing dolfinx first failed ("libmpi.so.12: cannot open shared object
# file"). A .pth line loads the library (no MPI_Init) at interpreter start, in any import order.
site="$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
echo "import os, sys, ctypes; _p = os.path.join(sys.prefix, 'lib', 'libmpi.so.12'); os.path.exists(_p) and ctypes.CDLL(_p, mode=ctypes.RTLD_GLOBAL)" \
  > "$site/mpfem_libmpi_first.pth"
echo "$want" > "$stamp"
echo "bootstrap: done"
