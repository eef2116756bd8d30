#!/usr/bin/env bash
# One entry point for a fresh machine:
#   scripts/lgp.sh run    install what is missing, build the `lgp` CLI (Release) and only it,
#                         run the example search
#   scripts/lgp.sh test   install what is missing, build everything (Release), run the whole
#                         test suite
#   scripts/lgp.sh deps   only install the Debian packages
#   scripts/lgp.sh build [TARGET...]  install + build the targets (default: everything)
#   scripts/lgp.sh install [PREFIX]   build lgp, lgpd and the libraries, and install them,
#                         their headers and the CMake package under PREFIX (default ~/.local)
# Environment: BUILD_DIR (default build/release), JOBS (default nproc).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# Absolute, so that a relative BUILD_DIR means the same folder in every step.
BUILD_DIR="$(realpath -m "${BUILD_DIR:-$ROOT/build/release}")"
JOBS="${JOBS:-$(nproc)}"

# Debian packages the project builds, tests and benchmarks with. Nothing is downloaded at
# build time and nothing is vendored.
PACKAGES=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev nlohmann-json3-dev libspdlog-dev libcxxopts-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcpp-httplib-dev libsqlite3-dev
  openmpi-bin libopenmpi-dev
  glslang-tools glslang-dev libvulkan-dev mesa-vulkan-drivers
  chromium
)

deps() {
  local missing=()
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if ((${#missing[@]} == 0)); then
    echo "lgp: all ${#PACKAGES[@]} packages present"
    return
  fi
  echo "lgp: installing ${missing[*]}"
  local sudo=""
  if [[ $(id -u) -ne 0 ]]; then sudo="sudo"; fi
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null
}

# Configures the whole project (tests and benchmarks included, so a later `test` reuses the
# build tree) and builds the given targets, or everything.
build() {
  # Ninja schedules every compile of the project in one graph; make waits at each library's
  # end with one core idle. An existing build tree keeps the generator it was made with.
  local gen=()
  if [[ ! -f "$BUILD_DIR/CMakeCache.txt" ]] && command -v ninja >/dev/null; then gen=(-G Ninja); fi
  cmake -S "$ROOT" -B "$BUILD_DIR" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release >/dev/null
  if (($# > 0)); then
    cmake --build "$BUILD_DIR" -j "$JOBS" --target "$@"
  else
    cmake --build "$BUILD_DIR" -j "$JOBS"
  fi
}

cmd="${1:-}"
case "$cmd" in
  deps) deps ;;
  build)
    shift
    deps; build "$@"
    ;;
  run)
    # The example needs the CLI only; tests and benchmarks are built by `test`.
    deps; build lgp
    # The config's output paths are relative to it: the front lands in examples/.
    "$BUILD_DIR/frontends/lgp" run "$ROOT/examples/quickstart.json"
    "$BUILD_DIR/frontends/lgp" front "$ROOT/examples/quickstart-front.json"
    ;;
  install)
    prefix="$(realpath -m "${2:-$HOME/.local}")"
    deps; build lgp_installables
    cmake --install "$BUILD_DIR" --prefix "$prefix"
    echo "lgp: installed lgp and lgpd in $prefix/bin; put it on PATH with"
    echo "  export PATH=\"$prefix/bin:\$PATH\""
    ;;
  test)
    deps; build
    ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$JOBS" --timeout 600
    ;;
  *)
    echo "usage: scripts/lgp.sh run|test|deps|build|install [PREFIX]" >&2
    exit 2
    ;;
esac
