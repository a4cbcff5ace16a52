#!/usr/bin/env bash
# feedid watch's throughput with a broker on the same machine (issue 16): AXES axes at 1 kHz (binary payload, 0.1 s a
# message) from one `feedid publish --copies`, `feedid watch` pinned to one core; every 10 s its CPU (share of one
# core over the interval) and resident memory, then the first and last memory.
#   scripts/bench_watch.sh FEEDID [AXES=1000] [SECONDS=600] [CORE=0]
set -euo pipefail
feedid=${1:?usage: scripts/bench_watch.sh FEEDID [AXES] [SECONDS] [CORE]}
axes=${2:-1000}
seconds=${3:-600}
core=${4:-0}
[ -x /usr/sbin/mosquitto ] || { echo "bench_watch: no /usr/sbin/mosquitto (apt install mosquitto)" >&2; exit 77; }
dir=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do pkill -P "$p" 2>/dev/null || true; kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$dir"
}
trap cleanup EXIT
port=$(/usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
printf 'listener %s 127.0.0.1\nallow_anonymous true\npersistence false\nmax_queued_messages 100000\n' "$port" \
  > "$dir/mosquitto.conf"
/usr/sbin/mosquitto -c "$dir/mosquitto.conf" > "$dir/mosquitto.log" 2>&1 &
pids+=($!)
sleep 0.5
# the demo drive's synthetic test trace, replayed in a loop (each pass a later recording)
"$feedid" synth --out "$dir/trace.csv" > /dev/null 2>&1
# the service's memory bounds raised for AXES axes (0.95 MB of identifiers each at 1 kHz: the windows judged without
# and with the offset), the queue as before
printf '[service]\nestimate_interval_s = 5\nqueue_mb = 256\nmax_axes = %s\naxes_mb = %s\n' "$axes" \
  $(( axes + 16 )) > "$dir/watch.toml"
taskset -c "$core" "$feedid" watch --broker "mqtt://127.0.0.1:$port" --config "$dir/watch.toml" --topic 'bench/+/+/axis/#' --quiet \
  > "$dir/watch.out" 2> "$dir/watch.err" &
watch=$!
pids+=($watch)
sleep 0.5
# the trace replayed in a loop, AXES copies, real time; each pass continues the time of the last (one stream)
samples=$(($(grep -vc '^#' "$dir/trace.csv") - 1))
(
  for ((k = 0; ; k++)); do
    "$feedid" publish "$dir/trace.csv" --broker "mqtt://127.0.0.1:$port" --topic 'bench/B{n}/X/axis' \
      --copies "$axes" --binary --batch 0.1 --rate 1x --time-offset "$(awk -v k=$k -v n=$samples 'BEGIN { print k * n / 1000 }')" \
      --force-constant force_constant_N_per_A 2>> "$dir/publish.err" || exit 0
  done
) &
pids+=($!)
ticks=$(getconf CLK_TCK)
cpu() { awk '{print $14 + $15}' "/proc/$watch/stat"; }
rss() { awk '/VmRSS/ {print $2}' "/proc/$watch/status"; }
echo "seconds  cpu_%_of_one_core  rss_MB"
last_cpu=$(cpu)
first_rss=""
for ((t = 10; t <= seconds; t += 10)); do
  sleep 10
  now_cpu=$(cpu)
  now_rss=$(rss)
  [ -z "$first_rss" ] && [ "$t" -ge 30 ] && first_rss=$now_rss
  awk -v t="$t" -v d="$((now_cpu - last_cpu))" -v hz="$ticks" -v r="$now_rss" \
    'BEGIN { printf "%7d  %17.1f  %6.1f\n", t, 100 * d / hz / 10, r / 1024 }'
  last_cpu=$now_cpu
done
kill -TERM "$watch"
wait "$watch" || true
tail -1 "$dir/watch.err"
echo "memory from 30 s to the end: $((first_rss / 1024)) MB -> $((now_rss / 1024)) MB"
