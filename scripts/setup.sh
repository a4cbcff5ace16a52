#!/usr/bin/env bash
# Installs what feedid needs to build and test, from Debian's packages. Run as root it installs what is missing;
# otherwise it prints the one apt command to run and fails.
#   scripts/setup.sh          build and test dependencies
#   scripts/setup.sh --extra  also the optional test tools (LinuxCNC's interpreter, Chromium) where installable, and
#                             pandas for the Python side of bench_history
set -euo pipefail

packages=(cmake g++ make pkg-config libeigen3-dev libcli11-dev libfmt-dev nlohmann-json3-dev libfast-float-dev
          libmatio-dev zlib1g-dev libpugixml-dev libsqlite3-dev libssl-dev libgtest-dev libgmock-dev libbenchmark-dev
          libtomlplusplus-dev
          # the history on PostgreSQL: libpq (the client the backend is built with) and the server its tests start
          libpq-dev postgresql
          # feedid watch / publish: Eclipse Mosquitto's C client library, and its broker (with mosquitto_passwd) for the
          # tests and make demo; openssl makes the TLS tests' CA and certificates
          libmosquitto-dev mosquitto openssl
          # the Python module (pybind11, numpy) and its tests: pytest, pandas, scipy (the benchmark's reference),
          # Dask (feedid.fleet), and an offline `pip install --no-build-isolation .` into a venv
          python3-dev pybind11-dev python3-pybind11 python3-numpy python3-pytest python3-pandas python3-scipy
          python3-dask python3-distributed python3-setuptools python3-wheel python3-venv python3-pip)
extra=(linuxcnc-uspace chromium clang libclang-rt-14-dev universal-ctags)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
want_extra=0
[ "${1:-}" = "--extra" ] && want_extra=1
extra_missing=()
if [ $want_extra = 1 ]; then
  for p in "${extra[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || extra_missing+=("$p")
  done
fi

[ ${#missing[@]} -eq 0 ] && [ ${#extra_missing[@]} -eq 0 ] && exit 0

if [ "$(id -u)" != 0 ]; then
  echo "feedid needs these Debian packages: ${missing[*]} ${extra_missing[*]}" >&2
  echo "install them with:  sudo apt-get install -y ${missing[*]} ${extra_missing[*]}" >&2
  exit 1
fi

export DEBIAN_FRONTEND=noninteractive
apt-get update -q >/dev/null
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}" >&2
  apt-get install -y -q --no-install-recommends "${missing[@]}" >/dev/null
fi
# The optional tools: each on its own, so that one that cannot be installed does not stop the others;
# the tests that need them say so and skip.
for p in "${extra_missing[@]}"; do
  echo "setup: installing optional $p" >&2
  apt-get install -y -q --no-install-recommends "$p" >/dev/null 2>&1 || echo "setup: could not install $p (tests that need it will be skipped)" >&2
done
