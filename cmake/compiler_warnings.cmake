# Warnings live on an INTERFACE target that each lobe target links PRIVATE, so that consumers
# of lobe never inherit our flags.
add_library(lobe_warnings INTERFACE)
target_compile_options(lobe_warnings INTERFACE
  $<$<CXX_COMPILER_ID:GNU,Clang>:-Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
    -Wold-style-cast -Wcast-align -Woverloaded-virtual -Wconversion
    -Wdouble-promotion -Wformat=2 -Wimplicit-fallthrough>
  $<$<BOOL:${LOBE_WARNINGS_AS_ERRORS}>:-Werror>)
install(TARGETS lobe_warnings EXPORT lobeTargets)

# Helper: add_lobe_library(<short> SOURCES ...) creates lobe_<short> (STATIC) with alias
# lobe::<short>, its public include dir, and install rules.
function(add_lobe_library short)
  cmake_parse_arguments(ARG "" "" "SOURCES" ${ARGN})
  set(target lobe_${short})
  add_library(${target} STATIC ${ARG_SOURCES})
  add_library(lobe::${short} ALIAS ${target})
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_compile_features(${target} PUBLIC cxx_std_17)
  target_link_libraries(${target} PUBLIC lobe::core PRIVATE lobe_warnings)
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${short} POSITION_INDEPENDENT_CODE ON)
  install(TARGETS ${target} EXPORT lobeTargets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(DIRECTORY include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endfunction()
