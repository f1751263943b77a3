#!/usr/bin/env bash
# Create the virtual environment and install Gecko with its test and dev dependencies.
# Usage: scripts/bootstrap.sh PYTHON VENV_DIR
# Gecko needs no system packages beyond a Python >= 3.11 with venv and pip: every native
# library (Pinocchio, coal, qhull, daqp) comes as a wheel from PyPI. The tests also use
# Node (the Khronos glTF validator, installed from tools/package-lock.json) and a headless
# Chromium with its driver (the viewer's browser tests); as root with apt-get they are
# installed here, otherwise those tests skip and say why.
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

can_apt() { command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; }
apt_updated=0
apt_install() {
  if [ "$apt_updated" = 0 ]; then apt-get update -qq; apt_updated=1; fi
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@"
}
if ! command -v npm >/dev/null 2>&1 && can_apt; then
  echo "installing nodejs and npm with apt-get (glTF validator for the tests)" >&2
  apt_install nodejs npm || echo "could not install nodejs/npm: glTF validation tests will skip" >&2
fi
if command -v npm >/dev/null 2>&1; then
  npm ci --prefix tools --no-audit --no-fund --loglevel=error \
    || echo "npm ci in tools/ failed: glTF validation tests will skip" >&2
fi
if ! { command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1; }; then
  if can_apt; then
    echo "installing chromium and chromium-driver with apt-get (viewer browser tests)" >&2
    apt_install chromium chromium-driver \
      || echo "could not install chromium: the viewer's browser tests will skip" >&2
  else
    echo "chromium/chromium-driver missing (not root): the viewer's browser tests will skip" >&2
  fi
fi
echo "Gecko installed in $venv"
