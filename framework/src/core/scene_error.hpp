// SceneError is one kind of InputError; both are declared in input_error.hpp.
#pragma once

#include "core/input_error.hpp"
