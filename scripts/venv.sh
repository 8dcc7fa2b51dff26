#!/usr/bin/env bash
# Creates (or reuses) the project's Python virtual environment in .venv and installs the
# packages the tests need. Prints the path of the venv's python.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
venv="$root/.venv"
stamp="$venv/.requirements.sha"
want=$(sha256sum "$root/requirements-test.txt" | cut -d' ' -f1)
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv" >&2
fi
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  "$venv/bin/python" -m pip install --disable-pip-version-check -q -r "$root/requirements-test.txt" >&2
  echo "$want" > "$stamp"
fi
echo "$venv/bin/python"
