#!/usr/bin/env bash
# The main job on the bundled example: simulate a KUKA KR 16 with realistic errors (geometry,
# joint compliance under three payloads, a laser tracker 3 m away and turned 30 deg),
# identify it, print nominal vs calibrated accuracy on held-out poses and write the
# calibrated model. Outputs go to out/example/.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bash "$root/scripts/install-deps.sh"
bash "$root/scripts/build.sh"
accura="$root/build/cli/accura"
out="$root/out/example"
mkdir -p "$out"

echo
echo "== 1. a measurement campaign on a simulated real KR 16 (SMR 80,40,150 mm from the flange)"
"$accura" simulate --robot kuka_kr16 --tool 80,40,150 --effects geometric,joint_compliance \
  --payloads 0,8,16 --noise-mm 0.02 --poses 300 --seed 1 \
  --out "$out/kr16_fit.csv" --truth "$out/kr16_truth.xml"
echo "== 2. held-out poses of the same robot, measured from the same station"
"$accura" simulate --robot "$out/kr16_truth.xml" --effects none --payloads 0,8,16 \
  --noise-mm 0.02 --poses 200 --seed 2 --out "$out/kr16_validate.csv"
echo "== 3. identify the complete model: geometry and joint compliance"
"$accura" identify --robot kuka_kr16 --tool 80,40,150 --params geometric,joint_compliance \
  --data "$out/kr16_fit.csv" --validate "$out/kr16_validate.csv" \
  --out "$out/kr16_calibrated.xml" --json "$out/kr16_summary.json"
echo
echo "outputs in $out: kr16_calibrated.xml (the calibrated model: use it as --robot),"
echo "kr16_summary.json (the numbers), kr16_truth.xml (the simulated real robot, for comparison)"
