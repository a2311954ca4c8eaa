# The installed CMake package: <prefix>/lib/cmake/rasterslam/ with rasterslamConfig.cmake,
# rasterslamConfigVersion.cmake, rasterslamTargets*.cmake (the libraries as rasterslam::<lib>,
# from install(TARGETS ... EXPORT rasterslamTargets) in libs/*) and RasterslamPlugin.cmake
# (rasterslam_add_plugin), so that plugins build out of tree (examples/plugin-template).
include(CMakePackageConfigHelpers)
set(RASTERSLAM_CMAKE_SUBDIR "${CMAKE_INSTALL_LIBDIR}/cmake/rasterslam")
set(RASTERSLAM_SHARE_SUBDIR "${CMAKE_INSTALL_DATADIR}/rasterslam")
# Keep in step with the PUBLIC link libraries of libs/*/CMakeLists.txt.
set(RASTERSLAM_PUBLIC_MRPT_COMPONENTS
  "containers system io serialization rtti math img poses obs maps graphs")
set(RASTERSLAM_PUBLIC_OPENCV_COMPONENTS "core features2d imgcodecs")

install(EXPORT rasterslamTargets NAMESPACE rasterslam:: FILE rasterslamTargets.cmake
  DESTINATION ${RASTERSLAM_CMAKE_SUBDIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/rasterslamConfig.cmake.in
  ${PROJECT_BINARY_DIR}/cmake/rasterslamConfig.cmake
  INSTALL_DESTINATION ${RASTERSLAM_CMAKE_SUBDIR}
  PATH_VARS CMAKE_INSTALL_LIBDIR CMAKE_INSTALL_INCLUDEDIR RASTERSLAM_PLUGIN_SUBDIR
            RASTERSLAM_SHARE_SUBDIR)
# 0.x: a plugin is built for one minor version (the plugin interface may change between).
write_basic_package_version_file(${PROJECT_BINARY_DIR}/cmake/rasterslamConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/cmake/rasterslamConfig.cmake
  ${PROJECT_BINARY_DIR}/cmake/rasterslamConfigVersion.cmake
  ${PROJECT_SOURCE_DIR}/cmake/RasterslamPlugin.cmake
  DESTINATION ${RASTERSLAM_CMAKE_SUBDIR})
