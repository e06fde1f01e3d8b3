# Third-party dependencies, all from Debian's packages (scripts/install-deps.sh installs them).
# Each library links only what it needs, PRIVATE; see docs/architecture.md.
find_package(ZLIB REQUIRED)
find_package(HDF5 REQUIRED COMPONENTS C)
find_package(GDCM REQUIRED)
list(APPEND CMAKE_MODULE_PATH ${PROJECT_SOURCE_DIR}/cmake)
find_package(NiftiIO REQUIRED)
find_package(assimp REQUIRED)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(Threads REQUIRED)
find_package(OpenMP REQUIRED)
find_package(OpenCV REQUIRED COMPONENTS core imgproc imgcodecs)
if(LOBE_BUILD_TOOLS)
  find_package(CLI11 REQUIRED)
  find_package(nlohmann_json 3 REQUIRED)
endif()
# libmesh: CGAL 5.5 (header-only; ImageIO for the labelled-image domain) and TBB for CGAL's
# parallel Mesh_3 (CGAL::TBB_support defines CGAL_LINKED_WITH_TBB).
find_package(CGAL 5.5 REQUIRED COMPONENTS ImageIO)
find_package(TBB REQUIRED)
include(CGAL_TBB_support)
# SuiteSparse 5.12 (Debian 12) ships no CMake config: CHOLMOD and the libraries it needs by name.
# Linked by absolute path, so the exported static lobe::mss needs no find module downstream.
find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse REQUIRED)
find_library(CHOLMOD_LIBRARY cholmod REQUIRED)
find_library(SUITESPARSE_CONFIG_LIBRARY suitesparseconfig REQUIRED)
set(CHOLMOD_LIBRARIES ${CHOLMOD_LIBRARY} ${SUITESPARSE_CONFIG_LIBRARY})
