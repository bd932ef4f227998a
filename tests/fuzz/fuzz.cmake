# libFuzzer targets for every reader (issue 7). Included from CMakeLists.txt
# when PM_FUZZ=ON; needs clang (CC=clang CXX=clang++), see scripts/fuzz.
# The readers and what they call are compiled into their own static library
# with -fsanitize=fuzzer-no-link,address,undefined (coverage + sanitizers);
# each target adds libFuzzer's main.
if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
  message(FATAL_ERROR "PM_FUZZ=ON needs clang: configure with CC=clang CXX=clang++ (scripts/fuzz does)")
endif()
set(PM_FUZZ_FLAGS -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined
    -fno-omit-frame-pointer -g)
add_library(pmfuzzcore STATIC
  libcore/src/base/error.cpp
  libcore/src/base/vec.cpp
  libcore/src/base/volume.cpp
  libcore/src/base/log.cpp
  libcore/src/base/stats.cpp
  libcore/src/base/atomic_file.cpp
  libcore/src/base/mesh.cpp
  libcore/src/io/volume_io.cpp
  libcore/src/io/volume_header.cpp
  libcore/src/io/frame.cpp
  libcore/src/io/nrrd.cpp
  libcore/src/io/vdb.cpp
  libcore/src/io/vdb_openvdb.cpp
  libcore/src/field/mesh_sdf.cpp
  libcore/src/field/mesh_sdf_openvdb.cpp
  libcore/src/baseline/marching_cubes_openvdb.cpp
  libcore/src/io/metaimage.cpp
  libcore/src/io/nifti.cpp
  libcore/src/io/inr.cpp
  libcore/src/io/gzip.cpp
  libcore/src/io/mesh.cpp
  libcore/src/io/mesh_cgal.cpp
  libcore/src/io/ply.cpp
  libcore/src/io/vtk.cpp
  libcore/src/io/medit.cpp
  libcore/src/io/gmsh.cpp
  libcore/src/io/polygon_soup.cpp
  libcore/src/io/tet_mesh.cpp
  libcore/src/io/vtu.cpp
  libcore/src/io/nektar.cpp
  libcore/src/field/field.cpp
  libcore/src/field/kernels.cpp
  libcore/src/field/volume_field.cpp
  libcore/src/field/implicits.cpp
  libcore/src/field/curvature.cpp
  libcore/src/field/sizing.cpp
  libcore/src/field/hp_field.cpp
  libcore/src/baseline/lattice_iso.cpp
  libcore/src/sample/particles.cpp
  libcore/src/sample/engine.cpp
  libcore/src/sample/surface_constraint.cpp
  tests/fuzz/fuzz_util.cpp
)
target_include_directories(pmfuzzcore PUBLIC libcore/include tests/fuzz ${NIFTI_INCLUDE_DIR}/nifti
  ${CLI11_INCLUDE_DIR} ${TEEM_INCLUDE_DIR} ${NIFTI_INCLUDE_DIR} ${TINYXML2_INCLUDE_DIR})
# OpenVDB linked in, not loaded as the plugin (src/io/openvdb_plugin.h).
target_compile_definitions(pmfuzzcore PUBLIC PM_VERSION="${PROJECT_VERSION}" PM_OPENVDB_LINKED)
target_compile_options(pmfuzzcore PUBLIC ${PM_FUZZ_FLAGS})
# TBB's concurrent_hash_map (OpenVDB's accessor registry, instantiated in
# vdb_openvdb.cpp) downcasts small sentinel pointer values, which UBSan's alignment
# check reports inside TBB's header; that check is off for this one file.
# OpenVDB also reads tile flags from the file straight into a bool
# (scripts/ubsan.supp), so the bool check is off for this file too.
set_source_files_properties(libcore/src/io/vdb_openvdb.cpp PROPERTIES COMPILE_OPTIONS "-fno-sanitize=alignment;-fno-sanitize=bool")
target_link_options(pmfuzzcore PUBLIC -fsanitize=address,undefined)
target_link_libraries(pmfuzzcore PUBLIC
  OpenVDB::openvdb TBB::tbb CGAL::CGAL nlohmann_json::nlohmann_json
  ${TEEM_LIBRARY} ${NIFTI_LIBRARY} ZLIB::ZLIB ${TINYXML2_LIBRARY} Threads::Threads)
if(ZNZ_LIBRARY)
  target_link_libraries(pmfuzzcore PUBLIC ${ZNZ_LIBRARY})
endif()

set(PM_FUZZ_TARGETS nrrd metaimage nifti inr vdb ply off obj stl seeds sizing nektar_mesh nektar_field)
foreach(t ${PM_FUZZ_TARGETS})
  add_executable(fuzz_${t} tests/fuzz/fuzz_${t}.cpp)
  target_link_libraries(fuzz_${t} PRIVATE pmfuzzcore)
  target_link_options(fuzz_${t} PRIVATE -fsanitize=fuzzer)
endforeach()
# Writes the seed corpus with the project's own writers (tests/fuzz/make_corpus.cpp).
add_executable(fuzz_make_corpus tests/fuzz/make_corpus.cpp)
target_link_libraries(fuzz_make_corpus PRIVATE pmfuzzcore)
list(TRANSFORM PM_FUZZ_TARGETS PREPEND fuzz_ OUTPUT_VARIABLE PM_FUZZ_TARGETS_FULL)
add_custom_target(fuzz_all)
add_dependencies(fuzz_all ${PM_FUZZ_TARGETS_FULL} fuzz_make_corpus)
