#!/usr/bin/env bash
# Install (with Debian's apt-get) whatever flexipde needs that is missing. Idempotent and quiet
# when everything is already there. Run as root on Debian 12. `setup.sh --peers` adds python3-torch.
set -euo pipefail
pkgs=(
  build-essential cmake pkg-config git
  petsc-dev libopenmpi-dev openmpi-bin
  libfftw3-dev libfftw3-mpi-dev libhdf5-openmpi-dev
  libgtest-dev
  python3-numpy python3-matplotlib python3-h5py
)
# --peers: also the autodiff peer of run/bench_peers.sh (PyTorch, large; not needed otherwise)
for arg in "$@"; do
  case "$arg" in
  --peers) pkgs+=(python3-torch) ;;
  *) echo "setup: unknown argument '$arg' (known: --peers)" >&2; exit 2 ;;
  esac
done
missing=()
for p in "${pkgs[@]}"; do
  st=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ "$st" == "install ok installed" ]] || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  SUDO=""
  [[ $(id -u) -eq 0 ]] || SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
