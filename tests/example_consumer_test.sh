#!/usr/bin/env bash
# Kiln as a package, end to end: install a build tree into a temporary prefix, build
# examples/consumer against it (Ninja, then Unix Makefiles; also against the build tree itself
# and through pkg-config), run the program, and check when kiln_add_blob rebuilds the blob.
#
#   example_consumer_test.sh SOURCE_DIR BUILD_DIR CXX_COMPILER
#
# Works on copies in a temporary directory (removed on exit): the source tree stays clean.
# Exit 77 (ctest: skipped) when ninja is not installed (scripts/install-deps installs it).
set -euo pipefail

src=$(realpath "$1")
build=$(realpath "$2")
cxx=$3

if ! command -v ninja >/dev/null; then
  echo "SKIP: ninja not found (apt-get install ninja-build, or scripts/install-deps)"
  exit 77
fi
# A ctest run under make must not hand make's job server to the builds below.
unset MAKEFLAGS MFLAGS MAKELEVEL

tmp=$(mktemp -d "${TMPDIR:-/tmp}/kiln-consumer.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
prefix=$tmp/prefix
scene=$tmp/src/scene

fail() {
  echo "FAIL: $*" >&2
  exit 1
}

# --- install: what a consumer needs and nothing of the compiler -------------------------------
cmake --install "$build" --prefix "$prefix" >/dev/null
for f in bin/kiln bin/kiln-dump lib/libkiln_runtime.a lib/cmake/Kiln/KilnConfig.cmake \
         lib/cmake/Kiln/KilnConfigVersion.cmake lib/cmake/Kiln/KilnAddBlob.cmake \
         lib/pkgconfig/kiln.pc include/kiln/runtime/blob.hpp include/kiln/schema/manifest_generated.h; do
  [ -e "$prefix/$f" ] || fail "not installed: $f"
done
[ ! -e "$prefix/include/kiln/compiler" ] || fail "compiler headers installed"
if grep -rlE '#include *["<](kiln/compiler|assimp)' "$prefix/include"; then
  fail "an installed header includes compiler code or Assimp"
fi

cp -r "$src/examples/consumer" "$tmp/src"

# The program's output on the example scene (a box on a backdrop, seen from above).
check_output() {  # program
  local out
  out=$("$1") || fail "$1 exited with $?"
  grep -qx 'hits: 128 of 288' <<<"$out" || fail "$1: wrong hit count:"$'\n'"$out"
  grep -qx 'centre: t = 9.000 on box' <<<"$out" || fail "$1: wrong centre hit:"$'\n'"$out"
  grep -qx '....++++++####++++++....' <<<"$out" || fail "$1: wrong silhouette:"$'\n'"$out"
}

configure() {  # build_dir generator cmake-args...
  local dir=$1 generator=$2
  shift 2
  cmake -S "$tmp/src" -B "$dir" -G "$generator" -DCMAKE_BUILD_TYPE=Release \
        -DCMAKE_CXX_COMPILER="$cxx" "$@" >"$dir.configure.log" 2>&1 \
    || { cat "$dir.configure.log"; fail "configure ($generator) failed"; }
}

# The Makefile generators delete a custom command's output when its rule changed, at generate
# time: "absent" before a build is then normal.
blob_mtime() { stat -c %.9Y "$1/scene.kiln" 2>/dev/null || echo absent; }

# Builds and asserts whether the blob step ran (its build line and its output's time stamp).
# Sleeps first so that a file touched just before is newer than the blob at file-system
# time-stamp granularity.
build_expect() {  # build_dir rebuilt|unchanged why
  local dir=$1 expect=$2 why=$3 before log
  before=$(blob_mtime "$dir")
  log=$(cmake --build "$dir" 2>&1) || { echo "$log"; fail "build failed ($why)"; }
  local ran=unchanged
  grep -q 'Compiling Kiln blob scene.kiln' <<<"$log" && ran=rebuilt
  [ "$ran" = "$expect" ] || { echo "$log"; fail "$why: blob $ran, expected $expect"; }
  if [ "$expect" = rebuilt ]; then
    [ "$(blob_mtime "$dir")" != "$before" ] || fail "$why: blob step ran but scene.kiln unchanged"
  else
    [ "$(blob_mtime "$dir")" = "$before" ] || fail "$why: scene.kiln rewritten"
  fi
}

touch_later() { sleep 0.1; touch "$@"; }

incremental_checks() {  # build_dir generator
  local dir=$1 generator=$2
  build_expect "$dir" unchanged "$generator: no-op rebuild"
  if [ "$generator" = Ninja ]; then
    ninja -C "$dir" -n -d explain 2>&1 | grep -q 'ninja: no work to do' || fail "ninja: work left"
  fi
  for input in backdrop.gltf backdrop.bin box.obj box.mtl; do
    touch_later "$scene/$input"
    build_expect "$dir" rebuilt "$generator: touched $input"
    build_expect "$dir" unchanged "$generator: no-op after touching $input"
  done
  touch_later "$tmp/src/main.cpp" "$tmp/src/CMakeLists.txt"
  build_expect "$dir" unchanged "$generator: touched main.cpp and CMakeLists.txt (unrelated)"
  touch_later "$prefix/bin/kiln"
  build_expect "$dir" rebuilt "$generator: new kiln executable"
  # Changing OPTIONS: Ninja sees the new command line, Makefiles the options stamp.
  configure "$dir" "$generator" -DSCENE_KILN_OPTIONS=--compress
  build_expect "$dir" rebuilt "$generator: OPTIONS changed"
  configure "$dir" "$generator" -DSCENE_KILN_OPTIONS=--compress
  build_expect "$dir" unchanged "$generator: reconfigured with the same OPTIONS"
  check_output "$dir/consumer"  # the compressed blob reads the same
}

for generator in Ninja "Unix Makefiles"; do
  dir=$tmp/build-${generator// /-}
  configure "$dir" "$generator" -DCMAKE_PREFIX_PATH="$prefix"
  cmake --build "$dir" >"$dir.build.log" 2>&1 || { cat "$dir.build.log"; fail "$generator build failed"; }
  [ -s "$dir/scene.kiln.d" ] || fail "$generator: kiln wrote no depfile"
  check_output "$dir/consumer"
  incremental_checks "$dir" "$generator"
  echo "ok: $generator"
done

# The package straight from the build tree, without installing.
configure "$tmp/build-tree" Ninja -DKiln_DIR="$build"
cmake --build "$tmp/build-tree" >"$tmp/build-tree.log" 2>&1 \
  || { cat "$tmp/build-tree.log"; fail "build against the build tree failed"; }
check_output "$tmp/build-tree/consumer"
echo "ok: Kiln_DIR=<build tree>"

# pkg-config: the same program, compiled and linked by hand. The library is static, hence --static.
export PKG_CONFIG_PATH=$prefix/lib/pkgconfig
read -ra pc_flags <<<"$(pkg-config --static --cflags --libs kiln)"
"$cxx" -std=c++20 -O1 -DKILN_CONSUMER_BLOB="\"$tmp/build-Ninja/scene.kiln\"" \
  "$tmp/src/main.cpp" -o "$tmp/consumer-pc" "${pc_flags[@]}" || fail "pkg-config build failed"
check_output "$tmp/consumer-pc"
echo "ok: pkg-config"
