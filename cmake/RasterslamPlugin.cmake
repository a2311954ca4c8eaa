# rasterslam_add_plugin(<name> SOURCES ... [LIBS ...])
# Builds a plugin as a MODULE library named librasterslam_plugin_<name>.so into the build
# tree's plugin folder, and installs it where the loader looks for it.
function(rasterslam_add_plugin name)
  cmake_parse_arguments(P "" "" "SOURCES;LIBS" ${ARGN})
  set(target rasterslam_plugin_${name})
  add_library(${target} MODULE ${P_SOURCES})
  target_link_libraries(${target} PRIVATE rasterslam::core ${P_LIBS} rasterslam_warnings)
  set_target_properties(${target} PROPERTIES
    LIBRARY_OUTPUT_DIRECTORY "${RASTERSLAM_BUILD_PLUGIN_DIR}"
    INSTALL_RPATH "$ORIGIN/../..")
  install(TARGETS ${target} LIBRARY DESTINATION ${RASTERSLAM_PLUGIN_SUBDIR})
endfunction()
