#!/usr/bin/env bash
# The main job of `make demo`:
#   scripts/demo.sh BUILD/feedid            a synthetic trace of the paper's drive (feedid synth), its summary
#                                           (feedid info), the identified parameters beside the true ones (feedid
#                                           identify), the controller gains (feedid gains) and the closed-loop
#                                           validation (feedid simulate)
#   scripts/demo.sh BUILD/feedid DATA [ARGS...]
#                                           feedid info and feedid identify on the user's own file; ARGS (or the
#                                           environment variable FEEDID_ARGS) go to both, e.g. --channel current=iq
#                                           --kt 1.44 --lead 20
set -uo pipefail

feedid=${1:?usage: scripts/demo.sh FEEDID [DATA [ARGS...]]}
data=${2:-}
shift $(( $# >= 2 ? 2 : 1 ))
# shellcheck disable=SC2206
extra=(${FEEDID_ARGS:-} "$@")

if [ -n "$data" ]; then
  echo "== feedid info $data"
  "$feedid" info "$data" "${extra[@]}" || exit $?
  echo
  echo "== feedid identify $data"
  "$feedid" identify "$data" "${extra[@]}"
  status=$?
  [ $status -ne 0 ] && echo "demo: feedid identify exited with $status (see its message above)" >&2
  exit $status
fi

out=$(dirname "$feedid")/demo
mkdir -p "$out"
trace=$out/demo-trace.csv
echo "== feedid synth --out $trace"
echo "   the paper's drive (M 69.1 kg, B 54.2 N*s/m, F_C 742.8 N, F_B 946.2 N) with v_s 5 mm/s, in closed loop with a"
echo "   P-PI controller, on the constant-velocity test with slow passes; 10 nm encoder, seeded current noise"
"$feedid" synth --out "$trace" --seed 1 || exit $?
echo
echo "== feedid info $trace"
"$feedid" info "$trace" || exit $?
echo

echo "== feedid identify $trace --force-constant force_constant_N_per_A"
failed=0
rm -f "$out/demo-result.json" "$out/demo-gains.json"
if "$feedid" identify "$trace" --force-constant force_constant_N_per_A --json "$out/demo-result.json" \
     > "$out/demo-identify.txt" 2> "$out/demo-identify.err"; then
  cat "$out/demo-identify.txt"
  echo
  echo "   identified beside the true values:"
  # The true values are the trace's '# true_... = value' lines; the identified ones the result document's
  # parameters (pretty-printed JSON: a key line, then its "value" line).
  awk -v result="$out/demo-result.json" '
    FNR == NR && /^# true_/ { key = substr($2, 6); truth[key] = $4; next }
    FNR == NR { next }
    /"parameters": \{/ { inside = 1; next }
    inside && /^  \}/ { inside = 0 }
    inside && /^    "[A-Za-z0-9_]+": \{/ { name = $1; gsub(/[":]/, "", name) }
    inside && /"stderr":/ { e = $2; gsub(/,/, "", e); stderr_of[name] = e }
    inside && /"value":/ { v = $2; gsub(/,/, "", v); value[name] = v; order[++n] = name }
    END {
      printf "   %-36s %14s %14s %18s\n", "parameter", "identified", "true", "off by (std. err.)"
      for (i = 1; i <= n; i++) {
        k = order[i]; t = ""
        if (k in truth) t = truth[k]
        else {
          # symmetric keys: the true forward value (the demo drive is symmetric)
          fw = k; sub(/_(N|Ns_per_m|m_per_s)$/, "_forward&", fw)
          if (fw in truth) t = truth[fw]
        }
        if (t == "" && k == "offset_N") t = truth["offset_N"]
        shown = value[k] == "null" ? "-" : sprintf("%.6g", value[k])
        off = "-"
        if (value[k] != "null" && t != "" && stderr_of[k] != "null" && stderr_of[k] > 0)
          off = sprintf("%+.1f", (value[k] - t) / stderr_of[k])
        printf "   %-36s %14s %14s %18s\n", k, shown, (t == "" ? "-" : sprintf("%.6g", t)), off
      }
    }' "$trace" "$out/demo-result.json"
else
  status=$?
  cat "$out/demo-identify.txt" 2>/dev/null
  cat "$out/demo-identify.err" >&2
  echo "demo: feedid identify exited with $status (see its message above)" >&2
  failed=$status
fi
echo

echo "== feedid gains $trace --force-constant force_constant_N_per_A"
# (stderr only on failure: it holds the notes on channel roles guessed from their names, which feedid info showed)
"$feedid" gains "$trace" --force-constant force_constant_N_per_A --json "$out/demo-gains.json" 2> "$out/demo-gains.err"
status=$?
if [ $status -ne 0 ]; then
  cat "$out/demo-gains.err" >&2
  echo "demo: feedid gains exited with $status (see its message above)" >&2
  [ $failed -eq 0 ] && failed=$status
fi
# The true gains: the trace's '# true_... = value' lines.
awk '/^# true_position_gain_per_s / { kv = $4 } /^# true_velocity_gain_N_s_per_m / { kp = $4 }
     /^# true_velocity_integral_gain_N_per_m / { ki = $4 }
     END { printf "   true: K_v %.6g 1/s (%.4g (m/min)/mm), K_p %.6g N*s/m, K_i %.6g N/m", kv, kv * 0.06, kp, ki
           if (ki > 0) printf " (T_n %.4g ms)", 1000 * kp / ki
           printf "\n" }' "$trace"
echo

if [ -s "$out/demo-result.json" ] && [ -s "$out/demo-gains.json" ]; then
  echo "== feedid simulate $trace --result demo-result.json --gains demo-gains.json"
  "$feedid" simulate "$trace" --force-constant force_constant_N_per_A --result "$out/demo-result.json" \
    --gains "$out/demo-gains.json" 2> "$out/demo-simulate.err"
  status=$?
  if [ $status -ne 0 ]; then
    cat "$out/demo-simulate.err" >&2
    echo "demo: feedid simulate exited with $status (see its message above)" >&2
    [ $failed -eq 0 ] && failed=$status
  fi
fi

# Second part, when this feedid has MQTT and the mosquitto broker is installed: feedid watch live over MQTT. A broker
# on a free local port, three synthetic machines (the example part programs) replayed at 20x real time by feedid
# publish, feedid watch printing each axis's estimate as it converges; then everything is stopped by its PID.
if [ -x /usr/sbin/mosquitto ] && ! "$feedid" watch --broker mqtt://127.0.0.1:1 2>&1 | grep -q "built without MQTT"; then
  echo
  mqtt=$out/mqtt
  mkdir -p "$mqtt"
  port=$(/usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  printf 'listener %s 127.0.0.1\nallow_anonymous true\npersistence false\n' "$port" > "$mqtt/mosquitto.conf"
  /usr/sbin/mosquitto -c "$mqtt/mosquitto.conf" > "$mqtt/mosquitto.log" 2>&1 &
  broker=$!
  programs=$(dirname "$0")/../examples/programs
  m=0
  for program in pocket contour drilling; do
    m=$((m + 1))
    "$feedid" synth --program "$programs/$program.ngc" --seed "$m" --out "$mqtt/M$m.csv" 2> /dev/null || exit $?
  done
  echo "== feedid watch --broker mqtt://127.0.0.1:$port, three machines (pocket, contour, drilling) at 20x"
  grep -h "^# [XYZ]_true_\(mass_kg\|viscous_forward_Ns_per_m\|coulomb_forward_N\|offset_N\) " "$mqtt/M1.csv" |
    awk '{ v[substr($2, 1, 1)] = v[substr($2, 1, 1)] sprintf(" %s %s", $2, $4) }
         END { for (a in v) print "   true (every machine):" v[a] }' | sort
  printf '[service]\nestimate_interval_s = 3\n' > "$mqtt/watch.toml"
  "$feedid" watch --broker "mqtt://127.0.0.1:$port" --config "$mqtt/watch.toml" --idle-exit 10 2> "$mqtt/watch.err" |
    tee "$mqtt/watch.out" &
  watch=$!
  sleep 0.5
  publishers=()
  for m in 1 2 3; do
    for axis in X Y Z; do
      "$feedid" publish "$mqtt/M$m.csv" --axis "$axis" --force-constant "${axis}_force_constant_N_per_A" \
        --broker "mqtt://127.0.0.1:$port" --topic "plant/M$m/$axis/axis" --rate 20x --binary \
        2>> "$mqtt/publish.err" &
      publishers+=($!)
    done
  done
  for p in "${publishers[@]}"; do wait "$p"; done
  wait "$watch"
  tail -1 "$mqtt/watch.err"
  # The last estimate of every axis of every machine beside the truth (Z carries a 35 N weight: the offset F_0 is
  # selected from the data; a Coulomb friction the windows cannot tell from it is '-', the reason in the document)
  echo
  echo "   final estimates (M1 pocket, M2 contour, M3 drilling) beside the truth:"
  for m in 1 2 3; do
    for axis in X Y Z; do
      grep "^M$m/$axis:" "$mqtt/watch.out" | tail -1 | sed 's/^/   /'
      awk -v a="$axis" '$2 == a"_true_mass_kg" { M = $4 } $2 == a"_true_viscous_forward_Ns_per_m" { B = $4 }
        $2 == a"_true_coulomb_forward_N" { C = $4 } $2 == a"_true_offset_N" { O = $4 }
        END { printf "   %-6s true: M %s kg  B %s N*s/m  F_C %s N", "", M, B, C
              if (O != 0) printf "  F_0 %s N", O
              printf "\n" }' "$mqtt/M$m.csv"
    done
  done
  kill "$broker"
  wait "$broker" 2> /dev/null
fi
exit $failed
