// Registers the sdf backend (the only translation unit of the plugin module).
#include "sdf_backend.hpp"

PINSIM_PLUGIN(pinsim::sdf::SdfBackend)
