#!/usr/bin/env bash
# Byte-identity check between two commits: runs the same commands (bundled suites on both twins for every
# bundled robot, convert, compare, align with CMA-ES / least squares / the prediction objective, an ensemble,
# predict-error, lockstep, perception collect, generate) with each commit's package, from the same fixed
# paths, and lists every output file that differs.
#
#   scripts/byte_identity.sh OLD_REV NEW_REV [WORK_DIR]     e.g. scripts/byte_identity.sh d5bfcdf HEAD
#
# Both trees are run with this checkout's virtualenv (.venv). The CLI's option shapes changed in the
# redesign (issue 18: --out everywhere, named runs in compare, `perception collect`); each tree is driven in
# its own shape, detected from its `convert --help`. Takes a few minutes per commit on 2 cores.
set -euo pipefail
OLD=$1; NEW=$2; WORK=${3:-${TMPDIR:-/tmp}/dualtwin-byte-identity}
REPO=$(cd "$(dirname "$0")/.." && pwd); PY=$REPO/.venv/bin/python
mkdir -p "$WORK"

run_tree() {  # run_tree REV NAME
  local SRC=$WORK/src OUT=$WORK/out
  rm -rf "$SRC" "$OUT"; mkdir -p "$SRC" "$OUT"
  git -C "$REPO" archive "$1" src | tar -x -C "$SRC"
  export PYTHONPATH=$SRC/src MUJOCO_GL=${MUJOCO_GL:-egl}
  DT() { "$PY" -c "import sys; from dualtwin.cli import main; sys.argv[0]='dualtwin'; sys.exit(main())" "$@" \
           >>"$OUT/log.txt" 2>&1 || echo "FAIL: $*" >>"$OUT/fail.txt"; }
  local R=$SRC/src/dualtwin/robots SHAPE=old
  if "$PY" -c "import sys; from dualtwin.cli import main; sys.argv[0]='dualtwin'; sys.exit(main())" convert --help \
       2>/dev/null | grep -qE -- "--out([^p]|$)"; then SHAPE=new; fi
  local O=-o; [ $SHAPE = new ] && O=--out
  for robot in cartpole pioneer3at arm arm_payload; do
    echo "[$2] $robot" >&2
    for twin in webots mujoco; do
      DT suite run --twin $twin --robot $robot --scenarios $R/$robot/suite.json --out $OUT/suite_${robot}_$twin
    done
    DT convert $R/$robot/$robot.wbt $O $OUT/convert_$robot.xml --binding $OUT/convert_$robot.binding.yaml
    if [ $SHAPE = old ]; then DT compare $OUT/suite_${robot}_webots $OUT/suite_${robot}_mujoco --out $OUT/compare_$robot
    else DT compare --reference-run $OUT/suite_${robot}_webots --target-run $OUT/suite_${robot}_mujoco --out $OUT/compare_$robot; fi
  done
  echo "[$2] align, sync, perception, generate" >&2
  local K="--knobs joint.pole_hinge.* --knobs body.pole.mass"
  DT align --target mujoco --reference webots --robot cartpole --scenarios $R/cartpole/suite.json $K --budget 24 --seed 3 --out $OUT/align_cartpole_cma
  DT align --target mujoco --reference webots --robot cartpole --scenarios $R/cartpole/suite.json $K --optimizer lsq --budget 24 --seed 3 --out $OUT/align_cartpole_lsq
  DT align --target mujoco --reference webots --robot arm --scenarios $R/arm/suite.json --knobs 'joint.*.damping' --optimizer lsq --budget 20 --seed 1 --out $OUT/align_arm_lsq
  DT align --target mujoco --reference webots --robot cartpole --scenarios $R/cartpole/suite.json --knobs joint.pole_hinge.damping --objective prediction --budget 12 --seed 2 --out $OUT/align_cartpole_pred
  DT predict-error --robot cartpole --scenarios $R/cartpole/suite.json --out $OUT/predict_cartpole
  DT lockstep --robot cartpole --scenarios $R/cartpole/suite.json --out $OUT/lockstep_cartpole
  DT suite run --twin mujoco --robot cartpole --scenarios $R/cartpole/suite.json --ensemble 3 --perturb initial_angle=0.01 --executor serial --out $OUT/ensemble_cartpole
  if [ $SHAPE = old ]; then DT collect --env dualtwin/CartPole-Webots-v0 --episodes 2 --seed 4 --out $OUT/collect_cartpole
  else DT perception collect --env dualtwin/CartPole-Webots-v0 --episodes 2 --seed 4 --out $OUT/collect_cartpole; fi
  DT generate --from-json $SRC/src/dualtwin/genai/cases/cartpole.json $O $OUT/generate_cartpole
  rm -rf "$WORK/$2"; mv "$OUT" "$WORK/$2"
}

run_tree "$OLD" old
run_tree "$NEW" new
"$PY" - "$WORK/old" "$WORK/new" <<'PYEOF'
import sys
from pathlib import Path
old, new = Path(sys.argv[1]), Path(sys.argv[2])
skip = {"log.txt", "fail.txt"}
files = lambda d: {p.relative_to(d).as_posix() for p in d.rglob("*") if p.is_file() and p.name not in skip}
a, b = files(old), files(new)
same = [f for f in sorted(a & b) if (old / f).read_bytes() == (new / f).read_bytes()]
for f in sorted(a - b): print("only in old:", f)
for f in sorted(b - a): print("only in new:", f)
for f in sorted((a & b) - set(same)): print("differs:", f)
for side, d in (("old", old), ("new", new)):
    if (d / "fail.txt").exists(): print(f"commands that failed ({side}):\n" + (d / "fail.txt").read_text())
print(f"{len(same)} of {len(a | b)} files byte-identical")
PYEOF
