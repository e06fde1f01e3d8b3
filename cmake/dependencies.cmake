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
if(LOBE_BUILD_TOOLS)
  find_package(CLI11 REQUIRED)
  find_package(OpenCV REQUIRED COMPONENTS core imgproc imgcodecs)
endif()
