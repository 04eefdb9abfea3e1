# The web build's dependencies (Emscripten): Eigen, nlohmann-json, spdlog, fmt and Boost's
# headers are header-only and come from Debian's include folder. -idirafter puts that folder
# after Emscripten's own libc/libc++ headers, so only what Emscripten lacks is taken from it.
set(PINSIM_HOST_INCLUDE_DIR /usr/include CACHE PATH "Where Debian's header-only libraries are")
set(PINSIM_WEB_PLUGINS sdf none gravity linear_spring damped_spring bending area_pressure
    CACHE STRING "Plugins linked into the web engine (backends and forces)")

add_library(pinsim_web_host_headers INTERFACE)
target_compile_options(pinsim_web_host_headers INTERFACE -idirafter ${PINSIM_HOST_INCLUDE_DIR})
# fmt (which spdlog uses) compiled into each file instead of Debian's libfmt.so.
target_compile_definitions(pinsim_web_host_headers INTERFACE FMT_HEADER_ONLY)
foreach(_t Eigen3::Eigen Boost::headers spdlog::spdlog nlohmann_json::nlohmann_json)
  string(MAKE_C_IDENTIFIER ${_t} _id)
  add_library(pinsim_web_${_id} INTERFACE)
  target_link_libraries(pinsim_web_${_id} INTERFACE pinsim_web_host_headers)
  add_library(${_t} ALIAS pinsim_web_${_id})
endforeach()
target_include_directories(pinsim_web_Eigen3__Eigen SYSTEM INTERFACE
                           ${PINSIM_HOST_INCLUDE_DIR}/eigen3)
# Native wasm exceptions (the engine reports bad input by throwing), in every object.
add_compile_options(-fwasm-exceptions)
add_link_options(-fwasm-exceptions)
set(PINSIM_BUILD_TESTS OFF CACHE BOOL "" FORCE)
set(PINSIM_BUILD_BENCH OFF CACHE BOOL "" FORCE)
set(PINSIM_STATIC_PLUGINS ON CACHE BOOL "" FORCE)
