# Installation and the CMake package: `cmake --install BUILD --prefix PREFIX` installs the libraries, their
# headers, the scenecal command with its odometry plugin, and PREFIX/lib/cmake/scenecal, so that another
# project's find_package(scenecal CONFIG) gives scenecal::core, scenecal::io, scenecal::sim, scenecal::report
# (docs/library.md). Included from the top-level CMakeLists.txt after the targets are defined.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(SCENECAL_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/scenecal)
set(SCENECAL_LIBRARIES core io sim report)

# A consumer compiles the headers as C++20 without setting it itself.
target_compile_features(scenecal_core PUBLIC cxx_std_20)
foreach(library ${SCENECAL_LIBRARIES})
  set_target_properties(scenecal_${library} PROPERTIES EXPORT_NAME ${library})
  # The same names inside this build (examples/ links scenecal::core both in and outside the build).
  add_library(scenecal::${library} ALIAS scenecal_${library})
  # Headers keep the include paths the sources use ("core/calibrate.hpp"): PREFIX/include/scenecal is the
  # libraries' include directory (INSTALL_INTERFACE in src/core/CMakeLists.txt names the same folder).
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/src/${library}/ DESTINATION include/scenecal/${library}
    FILES_MATCHING PATTERN "*.hpp")
endforeach()
# The static libraries link scenecal_warnings privately, which the export records as a link-only dependency;
# its compile flags never reach a consumer, its link flags do (the sanitizers' runtime with SCENECAL_SANITIZE).
set_target_properties(scenecal_warnings PROPERTIES EXPORT_NAME build_flags)
install(TARGETS scenecal_core scenecal_io scenecal_sim scenecal_report scenecal_warnings
  EXPORT scenecal-targets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(EXPORT scenecal-targets NAMESPACE scenecal:: DESTINATION ${SCENECAL_INSTALL_CMAKEDIR})

configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/scenecalConfig.cmake.in
  ${PROJECT_BINARY_DIR}/cmake/scenecalConfig.cmake INSTALL_DESTINATION ${SCENECAL_INSTALL_CMAKEDIR})
# 0.x: minor versions may break the API.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/cmake/scenecalConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/cmake/scenecalConfig.cmake ${PROJECT_BINARY_DIR}/cmake/scenecalConfigVersion.cmake
  DESTINATION ${SCENECAL_INSTALL_CMAKEDIR})

# The command, and the odometry plugin beside it: cli::LoadOdometryPlugin looks for it in the executable's folder
# only. Dependencies outside the system's folders stay found through the install RPATH.
set_target_properties(scenecal scenecal_odometry_plugin PROPERTIES INSTALL_RPATH_USE_LINK_PATH ON)
install(TARGETS scenecal RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(TARGETS scenecal_odometry_plugin LIBRARY DESTINATION ${CMAKE_INSTALL_BINDIR})

# Presets (config/), where the source tree has them.
install(DIRECTORY ${PROJECT_SOURCE_DIR}/config/ DESTINATION ${CMAKE_INSTALL_DATADIR}/scenecal/config OPTIONAL)
