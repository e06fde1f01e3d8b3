#!/usr/bin/env bash
# Sets up a fresh Debian machine, builds lobe (Release, warnings on) and runs the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake --preset release
cmake --build --preset release
ctest --preset release
