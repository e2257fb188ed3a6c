#!/usr/bin/env bash
# Set everything up, then run every test of tsplcam once:
#   1. engine tests with plain /usr/bin/python3 -m pytest (no FreeCAD),
#   2. the tests that need FreeCAD (document objects, OCCT comparisons; marked @needs_freecad
#      in tests/conftest.py): freecadcmd -t TestTsplcam,
#   3. GUI tests in the real FreeCAD GUI under Xvfb (screenshots land in build/artifacts).
# 1 runs as two pytest processes beside 2 and 3 (two cores). FreeCAD runs with an isolated user home (build/fchome)
# and HOME (build/home). Exit status 0 only when all three pass; each runner's summary line is
# printed at the end.
set -uo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$REPO/scripts/install.sh" || exit 1

export FREECAD_USER_HOME="${TSPLCAM_FC_HOME:-$REPO/build/fchome}"
export TSPLCAM_ARTIFACTS="${TSPLCAM_ARTIFACTS:-$REPO/build/artifacts}"
LOGS="$REPO/build/test-logs"
mkdir -p "$LOGS" "$TSPLCAM_ARTIFACTS" "$REPO/build/home"
FC_ENV=(env HOME="$REPO/build/home" FREECAD_USER_HOME="$FREECAD_USER_HOME" QTWEBENGINE_DISABLE_SANDBOX=1)
cd "$REPO"

SECONDS=0
# the machine, for reading a log's times (and last bits) later
echo "== machine:$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2-), $(nproc) cores, AVX-512" \
     "$(grep -qw avx512f /proc/cpuinfo && echo yes || echo no), load $(cut -d' ' -f1-3 /proc/loadavg)"
# 1 in the background, its output shown when it is done: two pytest processes, each test in
# one of them (shard a: the model, the plan, verify and the workbench's engine side; shard b:
# everything else, so a new test file lands there). On a 2-core AMD EPYC beside the FreeCAD
# runners: a 157 s and b 128 s with the toolpath tests in a; they are in b now (about 15 s).
SHARD_A=(tests/model tests/plan tests/verify tests/workbench
         tests/test_foundation.py tests/test_architecture.py)
/usr/bin/python3 -m pytest -q -p no:cacheprovider --durations=10 "${SHARD_A[@]}" \
    > "$LOGS/pytest-a.log" 2>&1 &
pid_py_a=$!
/usr/bin/python3 -m pytest -q -p no:cacheprovider --durations=10 tests "${SHARD_A[@]/#/--ignore=}" \
    > "$LOGS/pytest-b.log" 2>&1 &
pid_py_b=$!

echo "== 2/3 FreeCAD tests: freecadcmd -t TestTsplcam"
( cd "$REPO/build" && "${FC_ENV[@]}" freecadcmd -t TestTsplcam ) > "$LOGS/freecadcmd.log" 2>&1
rc_fc=$?
grep -E "^(ok|FAIL|ERROR|skipped)|\.\.\. (ok|FAIL|ERROR|skipped)" "$LOGS/freecadcmd.log" | tail -n 400 || true
if [ $rc_fc -ne 0 ]; then sed -n '/^======/,$p' "$LOGS/freecadcmd.log" | head -n 200; fi
# A module that fails to import shows as a failed test, so a missing line here is a failure too.
grep -qE "^Ran [0-9]+ tests?" "$LOGS/freecadcmd.log" || rc_fc=1

echo "== 3/3 GUI tests: freecad under xvfb-run"
rm -f "$LOGS/gui.result"
( cd "$REPO/build" && "${FC_ENV[@]}" TSPLCAM_GUI_RESULT="$LOGS/gui.result" timeout 1800 \
    xvfb-run -a -s "-screen 0 1280x1024x24" freecad "$REPO/tests/gui/run_gui_tests.py" ) \
    > "$LOGS/gui.log" 2>&1
rc_gui=$?
grep -E "\.\.\. (ok|FAIL|ERROR|skipped)" "$LOGS/gui.log" || true
if [ $rc_gui -ne 0 ]; then sed -n '/^======/,$p' "$LOGS/gui.log" | head -n 200; fi
[ -f "$LOGS/gui.result" ] && grep -q "^OK" "$LOGS/gui.result" || rc_gui=1

echo "== 1/3 engine tests: /usr/bin/python3 -m pytest (two shards)"
wait $pid_py_a
rc_py_a=$?
wait $pid_py_b
rc_py_b=$?
cat "$LOGS/pytest-a.log" "$LOGS/pytest-b.log"
rc_py=$(( rc_py_a != 0 || rc_py_b != 0 ))

echo
echo "== summary ($SECONDS s)"
echo "pytest (engine):     a: $(tail -n 1 "$LOGS/pytest-a.log")"
echo "                     b: $(tail -n 1 "$LOGS/pytest-b.log")"
echo "freecadcmd (FreeCAD): $(grep -E "^Ran [0-9]+ tests?" "$LOGS/freecadcmd.log" | tail -n 1) $(grep -E "^(OK|FAILED)" "$LOGS/freecadcmd.log" | tail -n 1)"
echo "freecad GUI (xvfb):  $(cat "$LOGS/gui.result" 2>/dev/null || echo 'no result: the GUI run did not finish')"
echo "screenshots:         $TSPLCAM_ARTIFACTS"
if [ $rc_py -eq 0 ] && [ $rc_fc -eq 0 ] && [ $rc_gui -eq 0 ]; then
  echo "tsplcam tests: PASSED"; exit 0
fi
echo "tsplcam tests: FAILED (pytest $rc_py, freecadcmd $rc_fc, gui $rc_gui)"; exit 1
