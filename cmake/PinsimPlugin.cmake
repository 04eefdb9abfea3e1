# pinsim_add_plugin(NAME SOURCES...): builds libpinsim_plugin_NAME.so, a module that
# exports only pinsim_plugin_entry, into the build tree's plugin folder and installs it.
# Used in-tree and, through the installed pinsimConfig.cmake, by out-of-tree authors
# (then the library lands in the author's build folder and is not installed).
#
# In-tree with PINSIM_STATIC_PLUGINS=ON (or the tests, tests/share) it also builds
# pinsim_static_NAME, a static library of the same sources whose entry function is
# pinsim_static_entry_NAME (PINSIM_STATIC_ENTRY in pinsim/detail/plugin_table.hpp), for the
# static plugin registry. In the web build (Emscripten) there are no modules:
# pinsim_plugin_NAME itself is that static library.
function(pinsim_add_plugin name)
  set(target pinsim_plugin_${name})
  if(EMSCRIPTEN)
    # In tree (the web preset) and out of tree (the web SDK, `pinsim share --source`).
    add_library(${target} STATIC ${ARGN})
    if(TARGET pinsim_options)
      target_link_libraries(${target} PRIVATE pinsim_sdk pinsim_options)
    else()
      if(name IN_LIST PINSIM_WEB_BUILTIN_PLUGINS)
        message(FATAL_ERROR "pinsim_add_plugin(${name}): the web engine already has a plugin "
                            "called '${name}'; give yours another name")
      endif()
      target_link_libraries(${target} PRIVATE pinsim::sdk)
      target_compile_options(${target} PRIVATE -Wall -Wextra -ffp-contract=off)
    endif()
    target_compile_definitions(${target} PRIVATE PINSIM_STATIC_ENTRY=pinsim_static_entry_${name})
    set_property(GLOBAL APPEND PROPERTY PINSIM_STATIC_PLUGIN_NAMES ${name})
    return()
  endif()
  if((PINSIM_STATIC_PLUGINS OR PINSIM_BUILD_TESTS) AND NOT PINSIM_OUT_OF_TREE
     AND TARGET pinsim_options)
    add_library(pinsim_static_${name} STATIC ${ARGN})
    target_link_libraries(pinsim_static_${name} PRIVATE pinsim_sdk pinsim_options)
    target_compile_definitions(pinsim_static_${name}
                               PRIVATE PINSIM_STATIC_ENTRY=pinsim_static_entry_${name})
    set_property(GLOBAL APPEND PROPERTY PINSIM_STATIC_PLUGIN_NAMES ${name})
    # At the end of the plugin's folder, where its find_package targets are visible.
    # (DEFER expands its arguments when the call runs: the name goes in as a literal.)
    cmake_language(EVAL CODE "cmake_language(DEFER CALL pinsim_link_static_twin [[${name}]])")
  endif()
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

# The static library holding plugin NAME's code with its static entry function.
function(pinsim_static_plugin_target name out)
  if(EMSCRIPTEN)
    set(${out} pinsim_plugin_${name} PARENT_SCOPE)
  else()
    set(${out} pinsim_static_${name} PARENT_SCOPE)
  endif()
endfunction()

# A static twin links what its plugin module links (the sdf backend's implementation
# library, Box2D, ...); called at the end of the plugin's folder.
function(pinsim_link_static_twin name)
  get_target_property(_libs pinsim_plugin_${name} LINK_LIBRARIES)
  foreach(_l IN LISTS _libs)
    if(NOT _l MATCHES "^pinsim_(sdk|options)$" AND NOT _l MATCHES "^pinsim::")
      target_link_libraries(pinsim_static_${name} PRIVATE ${_l})
    endif()
  endforeach()
endfunction()

# Links every static plugin into TARGET and adds the generated registration table, which
# registers each one (core/static_plugins.hpp) when the program starts.
function(pinsim_link_static_plugins target)
  get_property(_names GLOBAL PROPERTY PINSIM_STATIC_PLUGIN_NAMES)
  set(_decl "")
  set(_reg "")
  foreach(_n IN LISTS _names)
    pinsim_static_plugin_target(${_n} _t)
    target_link_libraries(${target} PRIVATE ${_t})
    string(APPEND _decl "extern \"C\" const pinsim_plugin* pinsim_static_entry_${_n}(void);\n")
    string(APPEND _reg "  pinsim::register_static_plugin(\"${_n}\", &pinsim_static_entry_${_n});\n")
  endforeach()
  set(_file ${CMAKE_CURRENT_BINARY_DIR}/${target}_static_plugin_table.cpp)
  # The registry's function is declared here, not included: the web SDK (`pinsim share
  # --source`) links this table against the prebuilt engine, without pinsim's private headers.
  file(CONFIGURE OUTPUT ${_file} CONTENT "// Generated by pinsim_link_static_plugins (cmake/PinsimPlugin.cmake).
#include <string>

struct pinsim_plugin;
namespace pinsim {
bool register_static_plugin(const std::string& name, const pinsim_plugin* (*entry)());
}  // namespace pinsim

${_decl}
namespace {
const bool registered = [] {
${_reg}  return true;
}();
}  // namespace
" @ONLY)
  target_sources(${target} PRIVATE ${_file})
endfunction()
