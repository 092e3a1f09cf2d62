#!/usr/bin/env bash
# The supported Python versions, each in a fresh virtual environment outside the checkout: build the wheel once,
# install it with its dependencies from the package index (with the pip that the Python's venv ships, as a user
# would), run `wbcbench run stand` and `wbcbench list` from it. With --tests, also install the extras 'test', 'dart'
# and 'c3d' and run a part of the test suite (the bridge, the QP solvers, the tasks, the simulator and the DART
# engine, standing, IK, inverse dynamics, the loop, the fast command line, C3D files) against the installed wheel,
# from a copy of tests/ without the source tree.
# Usage: bash scripts/test_pythons.sh [--tests] [PYTHON ...]   (default: python3.10 python3.11 python3.12 python3.13,
# each from the PATH or pyenv's installed versions; the wheel is built with .venv/bin/python, or $BUILD_PY)
# About 1-2 minutes a version without --tests, 3-4 with; see docs/release.md.
set -uo pipefail
cd "$(dirname "$0")/.."
TESTS=0
if [ "${1:-}" = "--tests" ]; then TESTS=1; shift; fi
PYTHONS=("$@")
[ ${#PYTHONS[@]} -eq 0 ] && PYTHONS=(python3.10 python3.11 python3.12 python3.13)
SUBSET=(tests/test_bridge.py tests/qp tests/tasks tests/sim tests/test_stand.py tests/test_ik.py
        tests/test_inverse_dynamics.py tests/test_loop.py tests/test_cli_fast.py tests/teleop/test_c3d.py)
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
git clone -q . "$WORK/src"
"${BUILD_PY:-.venv/bin/python}" -m build --wheel --outdir "$WORK/dist" "$WORK/src" > "$WORK/build.log" 2>&1 || { tail -5 "$WORK/build.log"; exit 1; }
WHEEL="$(ls "$WORK"/dist/*.whl)"
if [ $TESTS -eq 1 ]; then
    mkdir "$WORK/testtree"
    cp -r "$WORK/src/tests" "$WORK/src/pyproject.toml" "$WORK/testtree/"
fi
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
    target="$WHEEL"
    [ $TESTS -eq 1 ] && target="$WHEEL[test,dart,c3d]"
    start=$SECONDS
    if ! { "$py" -m venv "$v" > "$log" 2>&1 && "$v/bin/pip" install --quiet "$target" >> "$log" 2>&1; }; then
        echo "$name ($py): install FAILED: $(grep -v '^\s*$' "$log" | tail -1)"
        status=1
        continue
    fi
    took=$((SECONDS - start))
    pipv="$("$v/bin/pip" --version | cut -d' ' -f2)"
    if (cd "$WORK" && "$v/bin/wbcbench" run stand -c tsid-torque --duration 1 --quiet --out "$WORK/run-$tag" \
            >> "$log" 2>&1) \
        && (cd "$WORK" && "$v/bin/wbcbench" list >> "$log" 2>&1); then
        fell=$("$v/bin/python" -c "import json; print(json.load(open('$WORK/run-$tag/summary.json'))['fell'])")
        line="$name ($("$py" --version 2>&1), pip $pipv): installed in ${took}s, stand ran, fell=$fell"
    else
        echo "$name ($py): installed in ${took}s, stand or list FAILED: $(grep -v '^\s*$' "$log" | tail -1)"
        status=1
        continue
    fi
    if [ $TESTS -eq 1 ]; then
        start=$SECONDS
        # the venv's pytest (not `python -m pytest`, which would put the working directory first on sys.path),
        # from the copy of tests/: the wheel's wbcbench is the one imported
        (cd "$WORK/testtree" && "$v/bin/pytest" -x -p no:cacheprovider -n 2 "${SUBSET[@]}") > "$WORK/tests-$tag.log" 2>&1
        rc=$?
        result="$(grep -E '[0-9]+ (passed|failed|error)' "$WORK/tests-$tag.log" | tail -1 | sed 's/=//g; s/^ *//; s/ *$//')"
        line="$line; tests: ${result:-no summary} ($((SECONDS - start))s)"
        if [ $rc -ne 0 ]; then
            status=1
            grep -E '^(FAILED|ERROR)' "$WORK/tests-$tag.log" | head -5
            [ -z "$result" ] && tail -5 "$WORK/tests-$tag.log"
        fi
    fi
    echo "$line"
done
exit $status
