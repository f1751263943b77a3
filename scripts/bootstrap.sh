#!/usr/bin/env bash
# Create the virtual environment and install Gecko with its test and dev dependencies.
# Usage: scripts/bootstrap.sh PYTHON VENV_DIR
# Gecko needs no system packages beyond a Python >= 3.11 with venv and pip: every native
# library (Pinocchio, coal, qhull, daqp) comes as a wheel from PyPI.
set -euo pipefail
python=${1:-python3}
venv=${2:-.venv}

if ! "$python" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; then
  echo "Gecko needs Python >= 3.11; '$python' is $("$python" --version 2>&1)" >&2
  exit 1
fi
if ! "$python" -m venv --help >/dev/null 2>&1 || ! "$python" -c 'import ensurepip' 2>/dev/null; then
  if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    echo "installing python3-venv with apt-get" >&2
    apt-get update -qq && apt-get install -y -qq python3-venv python3-pip
  else
    echo "Python's venv module is missing: install python3-venv" >&2
    exit 1
  fi
fi
[ -x "$venv/bin/python" ] || "$python" -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --upgrade pip
"$venv/bin/python" -m pip install --quiet -e ".[test,dev]"
echo "Gecko installed in $venv"
