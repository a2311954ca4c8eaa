# Run as `cmake -DSOURCE_DIR=... -P CheckPluginAbi.cmake` (add -DUPDATE=ON to record): the
# public headers (libs/*/include) against the hash recorded with the plugin ABI number in
# libs/core/plugin-abi.txt. A plugin module carries the RASTERSLAM_PLUGIN_ABI of the headers it
# was built against (plugin.h), and the loader refuses another; the number only means
# something if it is raised whenever the classes and types plugins use change. This check makes
# every change of those headers a decision: raise the number, or record that it stays.
get_filename_component(SOURCE_DIR "${SOURCE_DIR}" ABSOLUTE)
set(record "${SOURCE_DIR}/libs/core/plugin-abi.txt")
file(READ "${SOURCE_DIR}/libs/core/include/rasterslam/core/plugin.h" pluginH)
if(NOT pluginH MATCHES "#define RASTERSLAM_PLUGIN_ABI ([0-9]+)")
  message(FATAL_ERROR "libs/core/include/rasterslam/core/plugin.h: no #define RASTERSLAM_PLUGIN_ABI <number>")
endif()
set(abi "${CMAKE_MATCH_1}")
file(GLOB includeDirs "${SOURCE_DIR}/libs/*/include")
set(headers "")
foreach(d ${includeDirs})
  file(GLOB_RECURSE found RELATIVE "${SOURCE_DIR}" "${d}/*.h")
  list(APPEND headers ${found})
endforeach()
list(SORT headers)
set(listing "")
foreach(h ${headers})
  file(SHA256 "${SOURCE_DIR}/${h}" sum)
  string(APPEND listing "${h} ${sum}\n")
endforeach()
string(SHA256 hash "${listing}")
list(LENGTH headers n)
set(expected "plugin_abi ${abi}\nheaders ${hash}\n")
if(UPDATE)
  file(WRITE "${record}.tmp" "${expected}")
  file(RENAME "${record}.tmp" "${record}")
  message("recorded plugin ABI ${abi} for the ${n} public headers in libs/core/plugin-abi.txt")
  return()
endif()
if(NOT EXISTS "${record}")
  message(FATAL_ERROR "libs/core/plugin-abi.txt is missing: record it with "
    "`cmake -DSOURCE_DIR=. -DUPDATE=ON -P cmake/CheckPluginAbi.cmake`")
endif()
file(READ "${record}" recorded)
if(NOT recorded STREQUAL expected)
  message(FATAL_ERROR "the public headers (libs/*/include, ${n} files) or RASTERSLAM_PLUGIN_ABI "
    "(${abi}) changed since libs/core/plugin-abi.txt was recorded:\n${recorded}"
    "If the change alters what a plugin built against them uses (a role class's virtual "
    "functions, a class's members or layout, a type passed to or from a plugin), raise "
    "RASTERSLAM_PLUGIN_ABI in libs/core/include/rasterslam/core/plugin.h; either way, record "
    "the headers with `cmake -DSOURCE_DIR=. -DUPDATE=ON -P cmake/CheckPluginAbi.cmake`.")
endif()
message("plugin ABI ${abi}: the ${n} public headers match their record")
