#!/usr/bin/env bash
# Installs the Debian packages accura needs, when they are missing (as root or with sudo).
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  libeigen3-dev       # linear algebra, transforms
  libceres-dev        # Levenberg-Marquardt for the identification
  libopenblas-serial-dev  # LAPACK's dense Cholesky (dpotrf) for the joint-map systems, with kernels
                          # picked for the processor at run time
  libtinyxml2-dev     # robot files and XML programs
  libassimp-dev       # CAD meshes of the cell (reach and clearance checks)
  libfcl-dev          # distance queries robot <-> cell meshes (clearance checks, BVH of OBBRSS)
  libgtest-dev        # tests
  libbenchmark-dev    # bench/
  liborocos-kdl-dev   # bench/: the IK peer (KDL ChainIkSolverPos_NR_JL)
  libcli11-dev        # command-line parsing
  liburdfdom-dev      # URDF import / export (urdfdom, the ROS parser; pulls console-bridge)
  liburdfdom-tools    # tests: check_urdf loads every exported URDF
  nlohmann-json3-dev  # JSON reports
  chromium            # tests: renders the diagnosis report headless and checks the screenshot
  libpng-dev          # tests: decodes that screenshot
  clang               # scripts/sanitize.sh (CI): the AddressSanitizer + UBSan build and the
                      # libFuzzer targets of fuzz/ (Debian 12: clang 14)
  libclang-rt-14-dev  # their runtimes (ASan, UBSan, libFuzzer) for clang 14
  freecad-python3     # plugin/freecad: FreeCAD's Robot workbench, run headless (freecadcmd) by the
                      # plug-in's FreeCAD test (151 packages, ~250 MB download, ~1.5 min to install)
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

if [ "$(id -u)" -eq 0 ]; then
  SUDO=()
elif command -v sudo >/dev/null 2>&1; then
  SUDO=(sudo)
else
  echo "install-deps: missing packages (${missing[*]}) and neither root nor sudo available" >&2
  exit 1
fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
"${SUDO[@]}" apt-get update -qq
"${SUDO[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
