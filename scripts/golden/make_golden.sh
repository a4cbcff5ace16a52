#!/usr/bin/env bash
# Writes the golden result documents of tests/system/test_golden.cpp with a given feedid binary:
#   scripts/golden/make_golden.sh BUILD/feedid [SHARED_DATA]
# Run it only when a change of numbers is intended, and say in the CHANGELOG which numbers moved and why.
# The documents are stored with the data folder and the demo trace's folder replaced by placeholders, so that the test
# can compare them wherever the data lives.
set -euo pipefail
feedid=${1:?usage: make_golden.sh FEEDID [SHARED_DATA]}
data=$(realpath "${2:-$(dirname "$0")/../../../shared/data}")
out=$(dirname "$0")/../../tests/golden
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
emps="$data/emps/DATA_EMPS.mat"
channels="--channel position=qm --channel reference_position=qg --channel current=vir --force-constant gtau"
normalise() { sed -e "s#$data#<DATA>#g" -e "s#$work#<WORK>#g"; }

"$feedid" identify "$emps" --channel position=qm --channel current=vir --force-constant gtau --offset \
    --json "$work/result.json" > /dev/null 2>&1
"$feedid" gains "$emps" $channels --saturation 10 --json "$work/gains.json" > /dev/null 2>&1
"$feedid" simulate "$emps" $channels --result "$work/result.json" --gains "$work/gains.json" \
    --json "$work/simulate.json" > /dev/null 2>&1
"$feedid" synth --out "$work/demo.csv" --seed 1 > /dev/null 2>&1
"$feedid" identify "$work/demo.csv" --force-constant force_constant_N_per_A --json "$work/demo.json" > /dev/null 2>&1 || true
normalise < "$work/result.json" > "$out/emps_identify.json"
normalise < "$work/gains.json" > "$out/emps_gains.json"
normalise < "$work/simulate.json" > "$out/emps_simulate.json"
normalise < "$work/demo.json" > "$out/demo_identify.json"
echo "wrote $out/{emps_identify,emps_gains,emps_simulate,demo_identify}.json"
