#!/usr/bin/env bash
# install_test.sh CMAKE BUILD_DIR CONSUMER_DIR CXX: install the build into a
# temporary prefix; the tools, headers, library and CMake package must be
# there, and a consumer project must configure, build and run against it.
set -euo pipefail
cmake=$1 build=$2 consumer=$3 cxx=$4
tmp=$(mktemp -d "${TMPDIR:-/tmp}/pm_install.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
prefix=$tmp/prefix
"$cmake" --install "$build" --prefix "$prefix" >"$tmp/install.log" || { cat "$tmp/install.log"; exit 1; }
for f in bin/particles bin/tetlabel bin/volconv include/pm/base/volume.h include/pm/mesh/pipeline.h \
         lib/libpmcore.a lib/cmake/particlemesh/particlemeshConfig.cmake; do
  [ -e "$prefix/$f" ] || { echo "install_test: $prefix/$f is missing after cmake --install" >&2; exit 1; }
done
"$prefix/bin/volconv" --version
"$cmake" -S "$consumer" -B "$tmp/build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_CXX_COMPILER="$cxx" >"$tmp/configure.log" 2>&1 || { cat "$tmp/configure.log"; exit 1; }
"$cmake" --build "$tmp/build" >"$tmp/build.log" 2>&1 || { cat "$tmp/build.log"; exit 1; }
"$tmp/build/consumer" "$tmp"
# The Python package, when it was built, installs beside them.
if [ -d "$build/python/particlemesh" ]; then
  site=$(/usr/bin/python3 -c 'import sys; print("lib/python%d.%d/dist-packages" % sys.version_info[:2])')
  PYTHONPATH="$prefix/$site" /usr/bin/python3 -c \
    'import particlemesh, sys; print("installed particlemesh", particlemesh.__version__, "from", particlemesh.__file__); sys.exit(0 if particlemesh.__file__.startswith(sys.argv[1]) else 1)' "$prefix"
fi
echo "install_test: ok"
