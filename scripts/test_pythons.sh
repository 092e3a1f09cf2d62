#!/usr/bin/env bash
# The supported Python versions, each in a fresh virtual environment outside the checkout: build the wheel once,
# install it with its dependencies from the package index, run `wbcbench run stand` and `wbcbench list` from it.
# Usage: bash scripts/test_pythons.sh [PYTHON ...]   (default: python3.10 python3.11 python3.12 python3.13; the
# wheel is built with .venv/bin/python, or $BUILD_PY)
set -uo pipefail
cd "$(dirname "$0")/.."
PYTHONS=("$@")
[ ${#PYTHONS[@]} -eq 0 ] && PYTHONS=(python3.10 python3.11 python3.12 python3.13)
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
git clone -q . "$WORK/src"
"${BUILD_PY:-.venv/bin/python}" -m build --wheel --outdir "$WORK/dist" "$WORK/src" > "$WORK/build.log" 2>&1 || { tail -5 "$WORK/build.log"; exit 1; }
WHEEL="$(ls "$WORK"/dist/*.whl)"
status=0
resolve() {  # a python3.X on the PATH, or pyenv's installed 3.X
    if "$1" --version > /dev/null 2>&1; then echo "$1"; return; fi
    local root; root="$(pyenv root 2>/dev/null || echo "$HOME/.pyenv")"
    ls -d "$root"/versions/"${1#python}".*/bin/"$1" 2>/dev/null | sort -V | tail -1
}
for name in "${PYTHONS[@]}"; do
    py="$(resolve "$name")"
    tag="$(basename "$name")"
    if [ -z "$py" ]; then echo "$name: not found"; status=1; continue; fi
    v="$WORK/venv-$tag"
    log="$WORK/$tag.log"
    if "$py" -m venv "$v" > "$log" 2>&1 && "$v/bin/pip" install --quiet "$WHEEL" >> "$log" 2>&1 \
        && (cd "$WORK" && "$v/bin/wbcbench" run stand -c tsid-torque --duration 1 --quiet --out "$WORK/run-$tag" \
            >> "$log" 2>&1) \
        && (cd "$WORK" && "$v/bin/wbcbench" list >> "$log" 2>&1); then
        fell=$("$v/bin/python" -c "import json; print(json.load(open('$WORK/run-$tag/summary.json'))['fell'])")
        echo "$name ($("$py" --version 2>&1)): installed, stand ran, fell=$fell"
    else
        echo "$name ($py): FAILED: $(grep -v '^\s*$' "$log" | tail -1)"
        status=1
    fi
done
exit $status
