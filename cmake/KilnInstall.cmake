# `cmake --install`: what a program reading blobs needs, nothing more. The runtime library with
# its public headers (formats, the generated manifest schema), the kiln and kiln-dump executables,
# the CMake package (find_package(Kiln): Kiln::runtime, Kiln::kiln, kiln_add_blob) and kiln.pc.
# The compiler library, tests and benchmarks are not installed: kiln links the compiler statically.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(KILN_CMAKE_INSTALL_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/Kiln)

# Destinations default to GNUInstallDirs' (lib/, include/, bin/).
install(TARGETS kiln_runtime kiln_formats kiln_schema kiln kiln-dump
  EXPORT KilnTargets
  FILE_SET HEADERS)
install(EXPORT KilnTargets NAMESPACE Kiln:: DESTINATION ${KILN_CMAKE_INSTALL_DIR})

# The same package from the build tree, without installing: -DKiln_DIR=<this build directory>.
export(EXPORT KilnTargets NAMESPACE Kiln:: FILE ${PROJECT_BINARY_DIR}/KilnTargets.cmake)
configure_package_config_file(cmake/KilnConfig.cmake.in ${PROJECT_BINARY_DIR}/KilnConfig.cmake
  INSTALL_DESTINATION ${KILN_CMAKE_INSTALL_DIR})
# 0.x: a new minor version may change the API, so only the same minor version is compatible.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/KilnConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
configure_file(cmake/KilnAddBlob.cmake ${PROJECT_BINARY_DIR}/KilnAddBlob.cmake COPYONLY)
install(FILES
    ${PROJECT_BINARY_DIR}/KilnConfig.cmake
    ${PROJECT_BINARY_DIR}/KilnConfigVersion.cmake
    ${PROJECT_BINARY_DIR}/KilnAddBlob.cmake
  DESTINATION ${KILN_CMAKE_INSTALL_DIR})

# pkg-config. The prefix is found from the .pc file's own location, so the file stays right
# under `cmake --install --prefix <elsewhere>`.
file(RELATIVE_PATH KILN_PC_PREFIX_FROM_PCFILEDIR
  ${CMAKE_INSTALL_FULL_LIBDIR}/pkgconfig ${CMAKE_INSTALL_PREFIX})
string(REGEX REPLACE "/$" "" KILN_PC_PREFIX_FROM_PCFILEDIR "${KILN_PC_PREFIX_FROM_PCFILEDIR}")
set(KILN_PC_SANITIZE_LIBS "")
if(KILN_SANITIZE)
  set(KILN_PC_SANITIZE_LIBS " -fsanitize=address,undefined")  # see runtime/CMakeLists.txt
endif()
configure_file(cmake/kiln.pc.in ${PROJECT_BINARY_DIR}/kiln.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/kiln.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
