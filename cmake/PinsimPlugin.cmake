# pinsim_add_plugin(NAME SOURCES...): builds libpinsim_plugin_NAME.so, a module that
# exports only pinsim_plugin_entry, into the build tree's plugin folder and installs it.
# Used in-tree and, through the installed pinsimConfig.cmake, by out-of-tree authors
# (then the library lands in the author's build folder and is not installed).
function(pinsim_add_plugin name)
  set(target pinsim_plugin_${name})
  add_library(${target} MODULE ${ARGN})
  if(TARGET pinsim::sdk)
    target_link_libraries(${target} PRIVATE pinsim::sdk)
  else()
    target_link_libraries(${target} PRIVATE pinsim_sdk)
  endif()
  if(TARGET pinsim_options)
    target_link_libraries(${target} PRIVATE pinsim_options)
  else()
    # Out of tree: the same floating-point contract as the host (no fused multiply-add).
    target_compile_options(${target} PRIVATE -Wall -Wextra -ffp-contract=off)
  endif()
  set_target_properties(${target} PROPERTIES PREFIX "lib" OUTPUT_NAME pinsim_plugin_${name}
                        CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON)
  if(DEFINED PINSIM_BUILD_PLUGIN_DIR)
    set_target_properties(${target} PROPERTIES LIBRARY_OUTPUT_DIRECTORY ${PINSIM_BUILD_PLUGIN_DIR})
  endif()
  set_property(GLOBAL APPEND PROPERTY PINSIM_PLUGIN_TARGETS ${target})
  if(DEFINED PINSIM_INSTALL_PLUGIN_DIR AND NOT PINSIM_OUT_OF_TREE)
    # Install relative to the prefix, so `cmake --install --prefix DIR` relocates plugins too.
    file(RELATIVE_PATH _rel ${CMAKE_INSTALL_PREFIX} ${PINSIM_INSTALL_PLUGIN_DIR})
    if(_rel MATCHES "^\\.\\.")
      set(_rel ${PINSIM_INSTALL_PLUGIN_DIR})
    endif()
    install(TARGETS ${target} LIBRARY DESTINATION ${_rel})
  endif()
endfunction()
