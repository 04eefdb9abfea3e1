# How a web engine is linked: the in-tree pinsim_web (framework/src/web) and the web SDK's
# link of an author's engine (pinsimWebConfig.cmake.in) use the same options.
set(PINSIM_WEB_LINK_OPTIONS
  -O2
  -fwasm-exceptions
  -sSINGLE_FILE=1
  -sMODULARIZE=1
  -sEXPORT_NAME=PinsimEngine
  -sALLOW_MEMORY_GROWTH=1
  -sENVIRONMENT=web,node
  "-sEXPORTED_RUNTIME_METHODS=['ccall','cwrap','UTF8ToString']")
