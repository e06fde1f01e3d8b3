# Finds nifti_clib's niftiio and znz libraries (Debian: libniftiio-dev, libznz-dev).
# Debian's own NIFTIConfig.cmake points at files that do not exist (/usr/lib/libznz.so.3.0.0),
# so we look the libraries up ourselves. Defines the imported target NiftiIO::niftiio.
find_path(NiftiIO_INCLUDE_DIR nifti1_io.h PATH_SUFFIXES nifti)
find_library(NiftiIO_LIBRARY niftiio)
find_library(NiftiIO_ZNZ_LIBRARY znz)
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(NiftiIO REQUIRED_VARS NiftiIO_LIBRARY NiftiIO_ZNZ_LIBRARY NiftiIO_INCLUDE_DIR)
if(NiftiIO_FOUND AND NOT TARGET NiftiIO::niftiio)
  find_package(ZLIB REQUIRED)
  add_library(NiftiIO::znz UNKNOWN IMPORTED)
  set_target_properties(NiftiIO::znz PROPERTIES IMPORTED_LOCATION ${NiftiIO_ZNZ_LIBRARY}
    INTERFACE_INCLUDE_DIRECTORIES ${NiftiIO_INCLUDE_DIR} INTERFACE_LINK_LIBRARIES ZLIB::ZLIB)
  add_library(NiftiIO::niftiio UNKNOWN IMPORTED)
  set_target_properties(NiftiIO::niftiio PROPERTIES IMPORTED_LOCATION ${NiftiIO_LIBRARY}
    INTERFACE_INCLUDE_DIRECTORIES ${NiftiIO_INCLUDE_DIR} INTERFACE_LINK_LIBRARIES "NiftiIO::znz;m")
endif()
mark_as_advanced(NiftiIO_INCLUDE_DIR NiftiIO_LIBRARY NiftiIO_ZNZ_LIBRARY)
