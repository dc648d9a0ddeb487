#!/usr/bin/env bash
# Installs what lightstage needs from Debian 12's packages (only what is missing), then configures
# and builds. Idempotent: a second run only rebuilds what changed.
#   BUILD_DIR  build directory (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}

PACKAGES=(
  g++ cmake ninja-build pkg-config ccache clang-format clang-tidy git
  clang libclang-rt-14-dev
  libomp-dev  # clang's OpenMP runtime: the sanitizer build links LibRaw, whose flags ask -fopenmp
  libopencv-core-dev libopencv-imgproc-dev libopencv-photo-dev libopencv-imgcodecs-dev
  libopencv-calib3d-dev libopencv-videoio-dev libopencv-video-dev
  libopenexr-dev libimath-dev libjpeg-dev libpng-dev libopenimageio-dev openimageio-tools
  libgpiod-dev gpiod libaravis-dev libusb-1.0-0-dev aravis-tools-cli
  libgphoto2-dev libraw-dev libtiff-dev  # DSLR domes: tethered cameras, raw files, test DNGs
  libeigen3-dev libglfw3-dev libgl-dev libegl-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libceres-dev libtbb-dev nlohmann-json3-dev libcli11-dev libimgui-dev zlib1g-dev
  libnanoflann-dev
  libmatio-dev  # MATLAB files: DiLiGenT's ground-truth normals (bench normals)
  libtinyobjloader-dev  # OBJ meshes: render --shape MESH.obj
  blender  # the exported glTF rendered by a real renderer (tests/relight/material)
  libopenmpi-dev openmpi-bin
  xvfb xauth mesa-utils
  gnuplot-nox  # the benches' charts (its pngcairo terminal)
  # The Python bindings (python/, docs/python.md), their tests and worked examples.
  python3-dev pybind11-dev python3-numpy python3-pytest python3-dask python3-matplotlib
  python3-scipy  # scripts/diligent_normals.py reads the benchmark's Normal_gt.mat
)

# Node.js runs the validators of exported glTF and MaterialX files (tests/tools); a machine with a
# Node.js of its own (which brings npm) keeps it.
command -v node >/dev/null || PACKAGES+=(nodejs)
command -v npm >/dev/null || PACKAGES+=(npm)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
# Paths below the checkout are hashed relative to it, so a clone elsewhere reuses the cache.
export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$PWD}
# Warnings are errors: this script builds with one known toolchain (Debian 12, GCC 12).
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release -DLIGHTSTAGE_WERROR=ON "${launcher[@]}" >/dev/null
echo "setup: building in $BUILD_DIR"
cmake --build "$BUILD_DIR" -j "$(nproc)"
# The validators the tests run on exported materials, from the npm registry (pinned): the Khronos
# glTF validator, and MaterialX's own core (WASM, with its standard libraries). Its peer
# dependency three.js is a renderer the validation does not load.
tools="$BUILD_DIR/node-tools"
if [ ! -f "$tools/.installed-1" ]; then
  echo "setup: installing the glTF and MaterialX validators into $tools"
  # Without the registry the tests that need them skip, saying so: not a reason to stop here.
  if npm install --prefix "$tools" --no-audit --no-fund --legacy-peer-deps --loglevel=error \
      gltf-validator@2.0.0-dev.3.10 @needle-tools/materialx@1.4.6 >/dev/null; then
    touch "$tools/.installed-1"
  else
    echo "setup: warning: the validators could not be installed (npm registry unreachable?):" \
      "the glTF and MaterialX validation tests will skip"
  fi
fi
