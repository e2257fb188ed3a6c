#!/usr/bin/env bash
# Set up everything tsplcam needs on Debian 12, idempotently.
#
#   bash scripts/install.sh            # packages + link into the isolated test home
#   bash scripts/install.sh --user     # also link into the real ~/.local/share/FreeCAD/Mod
#   bash scripts/install.sh --bench    # also the benchmarks' references (bench/requirements.txt)
#
# What it does:
#  1. Debian packages: FreeCAD 0.20 (freecad-python3, freecad), numpy, scipy, pip, pytest,
#     Xvfb + xauth for GUI tests, linuxcnc-uspace for LinuxCNC's own G-code interpreter (rs274),
#     matplotlib for the report's pictures (Debian 12's 3.6.3, built against Debian's numpy:
#     no wheel, so pip never replaces numpy; the check below asks for 3.5 or newer) with its
#     Pillow (python3-pil, a dependency of python3-matplotlib), which writes the pictures.
#  2. python-fcl and elkai, and for the tests hypothesis (with sortedcontainers, its one
#     dependency), into the system Python (/usr/bin/python3) that FreeCAD runs, pinned,
#     with --no-deps so pip never replaces Debian's numpy. For `batch --scheduler` (Dask):
#     distributed and dask, pinned, with --no-deps; their dependencies come from Debian where
#     Debian 12's version meets theirs (click, fsspec, jinja2, locket, msgpack, packaging,
#     psutil, pyyaml, tblib, toolz, tornado, zipp) and from pip, pinned, where it does not
#     (cloudpickle >= 3, partd >= 1.4, zict >= 3, importlib_metadata >= 4.13). numba (with its
#     llvmlite), pinned, with --no-deps, for the orientation's compiled kernels (optional: the
#     engine falls back to numpy without it); its kernels are compiled once here: ahead of time
#     (numba's pycc, with gcc, python3-dev and python3-distutils) into an extension module beside
#     the source that a job loads without numba, and into numba's cache for where it does not.
#  3. Links this checkout as the workbench "tsplcam" into an isolated FreeCAD user home
#     ($TSPLCAM_FC_HOME, default <repo>/build/fchome, used as FREECAD_USER_HOME); the user's real home only with --user.
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PY=/usr/bin/python3
APT_PACKAGES=(freecad-python3 freecad python3-numpy python3-scipy python3-pip python3-pytest
              xvfb xauth linuxcnc-uspace python3-matplotlib gcc python3-dev python3-distutils
              python3-click python3-fsspec python3-jinja2 python3-locket python3-msgpack python3-packaging
              python3-psutil python3-yaml python3-tblib python3-toolz python3-tornado python3-zipp)
PIP_PACKAGES=("python-fcl==0.7.0.11:fcl" "elkai==2.0.1:elkai"
              "sortedcontainers==2.4.0:sortedcontainers" "hypothesis==6.170.17:hypothesis"
              "cloudpickle==3.1.2:cloudpickle" "partd==1.4.2:partd" "zict==3.0.0:zict"
              "importlib_metadata==8.0.0:importlib_metadata" "dask==2026.8.0:dask"
              "distributed==2026.8.0:distributed" "llvmlite==0.42.0:llvmlite" "numba==0.59.1:numba")

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

say() { printf '[install] %s\n' "$*"; }

# 1. Debian packages ---------------------------------------------------------------
missing=()
for p in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  say "installing Debian packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
else
  say "Debian packages present"
fi

# 2. Wheels into the system Python ----------------------------------------------------
for spec in "${PIP_PACKAGES[@]}"; do
  req="${spec%%:*}"; mod="${spec##*:}"; want="${req##*==}"; dist="${req%%==*}"
  have="$($PY -c "import importlib.metadata as m; print(m.version('$dist'))" 2>/dev/null || true)"
  if [ "$have" != "$want" ] || ! $PY -c "import $mod" 2>/dev/null; then
    say "installing $req into $PY"
    $SUDO $PY -m pip install -q --break-system-packages --no-deps --root-user-action=ignore "$req"
  fi
done
$PY -c "import numpy, scipy, fcl, elkai, hypothesis, distributed, numba" || { say "a Python dependency does not import"; exit 1; }
$PY -c "import numpy, sys; sys.exit(not numpy.__file__.startswith('/usr/lib/python3/dist-packages/'))" \
  || { say "numpy is not Debian's python3-numpy any more (a wheel replaced it)"; exit 1; }
$PY -c "import matplotlib, PIL, sys; sys.exit(tuple(map(int, matplotlib.__version__.split('.')[:2])) < (3, 5))" \
  || { say "matplotlib 3.5 or newer with Pillow is needed for the report (python3-matplotlib)"; exit 1; }

# 3. Link the workbench -----------------------------------------------------------------
link_into() {  # $1 = a FreeCAD Mod directory
  mkdir -p "$1"
  local target="$1/tsplcam"
  if [ -L "$target" ] && [ "$(readlink -f "$target")" = "$REPO" ]; then return; fi
  if [ -e "$target" ] && [ ! -L "$target" ]; then
    say "refusing to replace $target: it is not a link (move it away first)"; exit 1
  fi
  ln -sfn "$REPO" "$target"
  say "linked $target -> $REPO"
}
# the compiled kernels: ahead of time into tsplcam/_aot_kernels*.so (kept while it is built
# from the current kernel source, tsplcam/compiled.py; a job then loads them in about a
# millisecond, without numba), and into numba's cache (beside the source) for a job that finds
# no current module (warmed by the orientation's calls of them, tsplcam/orientation/warmup.py)
PYTHONPATH="$REPO" $PY -c "from tsplcam.compiled import build_aot; build_aot()" \
  || say "the kernels do not compile ahead of time (numba.pycc, gcc): jobs load numba's instead"
PYTHONPATH="$REPO" $PY -c "from tsplcam.compiled import warm; from tsplcam.orientation.warmup import exercise; warm(exercise)" \
  || { say "the compiled kernels do not build (numba)"; exit 1; }
FC_HOME="${TSPLCAM_FC_HOME:-$REPO/build/fchome}"
# FreeCAD 0.20 with FREECAD_USER_HOME=$FC_HOME uses $FC_HOME itself as the user data directory.
link_into "$FC_HOME/Mod"
for arg in "$@"; do
  case "$arg" in
    --user) link_into "$HOME/.local/share/FreeCAD/Mod" ;;
    --bench)
      # 4. The benchmarks' references, pinned, never needed by the job itself ------------
      while read -r req; do
        req="${req%%#*}"; req="$(echo "$req" | tr -d '[:space:]')"
        [ -z "$req" ] && continue
        dist="${req%%==*}"; want="${req##*==}"
        have="$($PY -c "import importlib.metadata as m; print(m.version('$dist'))" 2>/dev/null || true)"
        if [ "$have" != "$want" ]; then
          say "installing $req into $PY (bench only)"
          $SUDO $PY -m pip install -q --break-system-packages --no-deps --root-user-action=ignore "$req"
        fi
      done < "$REPO/bench/requirements.txt"
      ;;
  esac
done
say "ready (FreeCAD test home: $FC_HOME)"
