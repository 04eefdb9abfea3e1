# PINSIM_WEB=ON in a native build: the web engine (pinsim_web.js, for `pinsim share`) is built
# by Emscripten in a sub-build at ${CMAKE_BINARY_DIR}/web, before `pinsim`.
include(ExternalProject)
set(PINSIM_EMSCRIPTEN_TOOLCHAIN /usr/share/emscripten/cmake/Modules/Platform/Emscripten.cmake
    CACHE FILEPATH "Emscripten's CMake toolchain file")
set(PINSIM_NODE_PATH /usr/share/nodejs CACHE PATH
    "NODE_PATH for Emscripten's tools (Debian's acorn lives in Debian's node modules folder)")
if(NOT EXISTS ${PINSIM_EMSCRIPTEN_TOOLCHAIN})
  message(FATAL_ERROR "PINSIM_WEB=ON needs Emscripten (Debian package emscripten): "
                      "${PINSIM_EMSCRIPTEN_TOOLCHAIN} not found")
endif()
set(_env ${CMAKE_COMMAND} -E env NODE_PATH=${PINSIM_NODE_PATH})
ExternalProject_Add(pinsim_web_build
  SOURCE_DIR ${PROJECT_SOURCE_DIR}
  BINARY_DIR ${CMAKE_BINARY_DIR}/web
  CONFIGURE_COMMAND ${_env} ${CMAKE_COMMAND} -S <SOURCE_DIR> -B <BINARY_DIR>
    -DCMAKE_TOOLCHAIN_FILE=${PINSIM_EMSCRIPTEN_TOOLCHAIN} -DCMAKE_BUILD_TYPE=Release
    -DPINSIM_WERROR=${PINSIM_WERROR} -DPINSIM_WITH_HDF5=OFF -DPINSIM_WITH_TBB=OFF
  BUILD_COMMAND ${_env} ${CMAKE_COMMAND} --build <BINARY_DIR> --target pinsim_web
  INSTALL_COMMAND ""
  BUILD_ALWAYS ON
  BUILD_BYPRODUCTS ${CMAKE_BINARY_DIR}/web/pinsim_web.js)
add_dependencies(pinsim pinsim_web_build)
