#!/usr/bin/env bash
# A plain, non-editable install with the core dependencies only (plus the test tools), used from
# outside the checkout: `contourmesh reproduce` must run, and the core tests must pass, the tests
# that need an optional peer or reader being skipped with a reason. CI runs this after the suite.
#   bash scripts/check_core_install.sh
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
py=${PYTHON:-python3}
echo "core-install: creating a fresh venv and installing contourmesh[dev] (not editable)" >&2
"$py" -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install -q --upgrade pip >/dev/null 2>&1 || true
"$tmp/venv/bin/python" -m pip install -q "$repo[dev]" 2>&1 | grep -v "^WARNING: Location" >&2 || true
"$tmp/venv/bin/python" -c "import contourmesh, sys; assert 'site-packages' in contourmesh.__path__[0], contourmesh.__path__"
cd "$tmp"
echo "core-install: contourmesh reproduce from outside the checkout" >&2
"$tmp/venv/bin/contourmesh" reproduce --out "$tmp/paper" --quiet
test -s "$tmp/paper/table1_sphere.csv"
echo "core-install: the core tests against the installed package" >&2
"$tmp/venv/bin/python" -m pytest -q -p no:cacheprovider -o addopts="-ra" --rootdir "$repo" \
  "$repo/tests/test_api.py" "$repo/tests/test_io.py" "$repo/tests/test_bad_inputs.py" "$repo/tests/test_cli.py" \
  "$repo/tests/test_reproduce.py" "$repo/tests/test_layers.py" "$repo/tests/test_compare_methods.py"
