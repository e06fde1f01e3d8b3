#!/usr/bin/env bash
# Installs the Debian packages lobe needs to build, test and run its demo.
# Idempotent: when every package is already installed it does nothing (no apt-get update).
# With --bench it also installs what the benchmarks need: tetgen (the meshing peer), ITK (the outside peer the segmentation
# benchmarks compare against; never a library dependency), matplotlib for the charts and scipy for
# bench/liver/surface_bias.py.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  zlib1g-dev libhdf5-dev libgdcm-dev libgdcm-tools libnifti2-dev libassimp-dev hdf5-tools
  libeigen3-dev libcgal-dev libgmp-dev libmpfr-dev libopencv-dev libsuitesparse-dev
  libcli11-dev nlohmann-json3-dev libgtest-dev libgmock-dev libbenchmark-dev
  libtbb-dev  # CGAL's parallel Mesh_3 (libmesh)
  # real files the tests read: ITK's example MetaImages and pydicom's DICOM test files
  insighttoolkit5-examples python3-pydicom
)

if [ "${1:-}" = "--bench" ]; then
  packages+=(libinsighttoolkit5-dev python3-matplotlib python3-numpy python3-pil python3-scipy tetgen)
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present" >&2
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}" >&2
$SUDO apt-get update
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y --no-install-recommends "${missing[@]}"
