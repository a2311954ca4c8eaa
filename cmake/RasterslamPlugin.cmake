# rasterslam_add_plugin(<name> SOURCES ... [LIBS ...])
# Builds a plugin as a MODULE library librasterslam_plugin_<name>.so (target
# rasterslam_plugin_<name>) linked to rasterslam::core and LIBS, and installs it into
# <prefix>/${RASTERSLAM_PLUGIN_SUBDIR} (lib/rasterslam/plugins), where the programs of the same
# prefix look for plugins.
# The same file serves the plugins/ folder of this project and, installed beside
# rasterslamConfig.cmake, plugins built out of tree with find_package(rasterslam); there:
# - the module is built into <build>/lib/rasterslam/plugins (RASTERSLAM_PLUGIN_PATH=that folder
#   runs it uninstalled);
# - RASTERSLAM_PLUGIN_SUBDIR is the folder the installed loader was built to search, and
#   RASTERSLAM_LIBRARY_DIR (the package's libraries) joins the module's RPATH, so a plugin
#   installed into another prefix still finds rasterslam::raster and the like.
function(rasterslam_add_plugin name)
  cmake_parse_arguments(P "" "" "SOURCES;LIBS" ${ARGN})
  if(P_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "rasterslam_add_plugin(${name}): unexpected arguments "
      "'${P_UNPARSED_ARGUMENTS}' (usage: rasterslam_add_plugin(<name> SOURCES ... [LIBS ...]))")
  endif()
  if(NOT P_SOURCES)
    message(FATAL_ERROR "rasterslam_add_plugin(${name}): no SOURCES given")
  endif()
  if(NOT name MATCHES "^[A-Za-z0-9_]+$")
    message(FATAL_ERROR "rasterslam_add_plugin(${name}): the name may hold letters, digits "
      "and '_' only (it becomes librasterslam_plugin_<name>.so)")
  endif()
  if(NOT RASTERSLAM_PLUGIN_SUBDIR)
    message(FATAL_ERROR "rasterslam_add_plugin(${name}): RASTERSLAM_PLUGIN_SUBDIR is not set "
      "(use find_package(rasterslam) before calling it)")
  endif()
  set(outdir "${RASTERSLAM_BUILD_PLUGIN_DIR}")
  if(NOT outdir)
    set(outdir "${CMAKE_BINARY_DIR}/lib/rasterslam/plugins")
  endif()
  set(target rasterslam_plugin_${name})
  add_library(${target} MODULE ${P_SOURCES})
  target_link_libraries(${target} PRIVATE rasterslam::core ${P_LIBS})
  if(TARGET rasterslam_warnings)  # this project's warning flags (in the source tree only)
    target_link_libraries(${target} PRIVATE rasterslam_warnings)
  endif()
  # The module sits two folders below the prefix's libraries.
  set(rpath "$ORIGIN/../..")
  if(RASTERSLAM_LIBRARY_DIR)
    list(APPEND rpath "${RASTERSLAM_LIBRARY_DIR}")
  endif()
  set_target_properties(${target} PROPERTIES
    PREFIX "lib"
    OUTPUT_NAME "rasterslam_plugin_${name}"
    SUFFIX ".so"
    LIBRARY_OUTPUT_DIRECTORY "${outdir}"
    INSTALL_RPATH "${rpath}")
  install(TARGETS ${target} LIBRARY DESTINATION ${RASTERSLAM_PLUGIN_SUBDIR})
endfunction()
