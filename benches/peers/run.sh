#!/bin/sh
# Run the mass-spring benchmark in Taichi and NVIDIA Warp beside lancet, on this machine, in
# one run: `benches/peers/run.sh [peers.py options]` from the repository root (for example
# `--preset undamped --sizes small`, or `--paired 100`). Installs the peers from PyPI into
# benches/peers/.venv on first use, and builds lancet's release binary and its Python package
# (which `--paired` steps in the peers' own process).
set -eu
here=$(dirname "$0")
venv="$here/.venv"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet numpy taichi==1.7.4 warp-lang==1.19.0
fi
cargo build --release --quiet -p lancet-cli -p lancet-python
stage=target/peers-python
rm -rf "$stage" && mkdir -p "$stage"
cp -r python/lancet "$stage/"
# The extension as Python names it: lib_lancet.so on Linux, lib_lancet.dylib on macOS.
for lib in target/release/lib_lancet.so target/release/lib_lancet.dylib; do
    if [ -f "$lib" ]; then cp "$lib" "$stage/lancet/_lancet.abi3.so"; fi
done
PYTHONPATH="$stage${PYTHONPATH:+:$PYTHONPATH}" \
    exec "$venv/bin/python" "$here/peers.py" --lancet target/release/lancet "$@"
