# CTest fixture: install this build of Obscura into a prefix and build the
# bent-normal plugin out of tree against it with find_package(obscura) -
# exactly what a third-party developer does.
#   cmake -DBUILD_DIR=... -DSOURCE_DIR=... -DOUT_DIR=... -P build_plugin.cmake
foreach(step install configure build)
  if(step STREQUAL install)
    file(REMOVE_RECURSE ${OUT_DIR}/prefix)  # a fresh prefix: only what this build installs
    set(cmd ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${OUT_DIR}/prefix)
  elseif(step STREQUAL configure)
    file(REMOVE_RECURSE ${OUT_DIR}/build)
    set(cmd ${CMAKE_COMMAND} -S ${SOURCE_DIR}/plugins/bent_normal -B ${OUT_DIR}/build
      -DCMAKE_PREFIX_PATH=${OUT_DIR}/prefix -DCMAKE_BUILD_TYPE=Release)
  else()
    set(cmd ${CMAKE_COMMAND} --build ${OUT_DIR}/build)
  endif()
  execute_process(COMMAND ${cmd} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "plugin ${step} failed (${rc}):\n${out}\n${err}")
  endif()
endforeach()
# The SDK is the only header set installed (docs/plugins.md "The SDK").
file(GLOB _installed RELATIVE ${OUT_DIR}/prefix/include ${OUT_DIR}/prefix/include/*)
if(NOT _installed STREQUAL "obscura")
  message(FATAL_ERROR "the package installs include/${_installed}; only include/obscura/ is the SDK")
endif()
if(NOT EXISTS ${OUT_DIR}/build/obscura_bent_normal.so)
  message(FATAL_ERROR "plugin build produced no obscura_bent_normal.so")
endif()
message(STATUS "built ${OUT_DIR}/build/obscura_bent_normal.so against ${OUT_DIR}/prefix")
