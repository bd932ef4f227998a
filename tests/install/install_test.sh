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
lib=
for f in "$prefix"/lib/libpmcore.so "$prefix"/lib/libpmcore.a; do [ -e "$f" ] && lib=$f; done
[ -n "$lib" ] || { echo "install_test: no libpmcore.so or libpmcore.a in $prefix/lib after cmake --install" >&2; exit 1; }
for f in bin/particles bin/tetlabel bin/volconv lib/libpmcore_openvdb.so include/pm/base/volume.h include/pm/mesh/pipeline.h \
         lib/cmake/particlemesh/particlemeshConfig.cmake; do
  [ -e "$prefix/$f" ] || { echo "install_test: $prefix/$f is missing after cmake --install" >&2; exit 1; }
done
# An installed tool runs from the prefix (finds the installed libpmcore).
"$prefix/bin/volconv" --version
"$cmake" -S "$consumer" -B "$tmp/build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_CXX_COMPILER="$cxx" >"$tmp/configure.log" 2>&1 || { cat "$tmp/configure.log"; exit 1; }
"$cmake" --build "$tmp/build" >"$tmp/build.log" 2>&1 || { cat "$tmp/build.log"; exit 1; }
"$tmp/build/consumer" "$tmp"
# The installed tools load OpenVDB through the installed plugin: a VDB round trip.
"$prefix/bin/volconv" "$tmp/consumer.nrrd" "$tmp/consumer.vdb" -q
"$prefix/bin/volconv" "$tmp/consumer.vdb" "$tmp/back.nrrd" -q
# Header, labels and value statistics the same, but for the file name.
if ! diff <("$prefix/bin/volconv" --info "$tmp/consumer.nrrd" | grep -v '"file"') \
          <("$prefix/bin/volconv" --info "$tmp/back.nrrd" | grep -v '"file"'); then
  echo "install_test: the volume changed in a VDB round trip through the installed plugin" >&2
  exit 1
fi
# The Python package, when it was built, installs beside them and loads the
# installed libpmcore: it reads the consumer's NRRD.
if [ -d "$build/python/particlemesh" ]; then
  site=$(/usr/bin/python3 -c 'import sys; print("lib/python%d.%d/dist-packages" % sys.version_info[:2])')
  PYTHONPATH="$prefix/$site" /usr/bin/python3 - "$prefix" "$tmp/consumer.nrrd" <<'PY'
import sys
import particlemesh
prefix, nrrd = sys.argv[1:3]
libs = [l.split()[-1] for l in open("/proc/self/maps") if "libpmcore" in l]
print("installed particlemesh", particlemesh.__version__, "from", particlemesh.__file__, "with", sorted(set(libs)))
assert particlemesh.__file__.startswith(prefix), particlemesh.__file__
assert libs and all(l.startswith(prefix) for l in libs), libs
v = particlemesh.read_volume(nrrd)
assert v.array.shape == (3, 4, 5) and v.array[2, 3, 4] == 59 and list(v.spacing) == [0.5, 0.5, 2.0], v
PY
fi
echo "install_test: ok"
