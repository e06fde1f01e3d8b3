# Sourced by bench/mss/run.sh and run_instruments.sh (needs $bin with lphantom and lmesh): the
# default phantom's liver (label 1) meshed by lmesh, serially (its serial meshes repeat exactly),
# in $MESHES when set (kept for the next run) or in a temporary folder.
if [ -n "${MESHES:-}" ]; then
  meshes="$MESHES"
  mkdir -p "$meshes"
else
  meshes="$(mktemp -d)"
  trap 'rm -rf "$meshes"' EXIT
fi
[ -f "$meshes/phantom/phantom.h5" ] || "$bin/lphantom" "$meshes/phantom" --quiet
# liver_mesh SIZE CF: prints the path of the liver meshed at --size SIZE --curvature-factor CF,
# making it first if it is not there.
liver_mesh() {
  local mesh="$meshes/liver_s$1.h5"
  [ -f "$mesh" ] || "$bin/lmesh" "$meshes/phantom/phantom.h5" --tissues 1 --size "$1" --curvature-factor "$2" \
    --threads 1 --quiet -o "$mesh" >&2
  echo "$mesh"
}
