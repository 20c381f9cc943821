#!/bin/sh
# Run the mass-spring benchmark in Taichi and NVIDIA Warp beside lancet, on this machine, in
# one run: `benches/peers/run.sh [peers.py options]` from the repository root (for example
# `--preset undamped --sizes small`). Installs the peers from PyPI into benches/peers/.venv on
# first use and builds lancet's release binary.
set -eu
here=$(dirname "$0")
venv="$here/.venv"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet numpy taichi==1.7.4 warp-lang==1.19.0
fi
cargo build --release --quiet --bin lancet
exec "$venv/bin/python" "$here/peers.py" --lancet target/release/lancet "$@"
