// Owning handles for cairo objects, so that a throw between create and destroy leaks
// nothing (std::unique_ptr with the library's own destroy function).
#pragma once

#include <cairo.h>

#include <memory>
#include <stdexcept>

namespace pinsim {

template <class T, void (*Destroy)(T*)>
struct CDeleter {
  void operator()(T* p) const {
    if (p != nullptr) Destroy(p);
  }
};

using CairoSurface =
    std::unique_ptr<cairo_surface_t, CDeleter<cairo_surface_t, cairo_surface_destroy>>;
using CairoContext = std::unique_ptr<cairo_t, CDeleter<cairo_t, cairo_destroy>>;

/// A new ARGB32 image surface; throws if cairo cannot make one.
inline CairoSurface image_surface(int width, int height) {
  CairoSurface s(cairo_image_surface_create(CAIRO_FORMAT_ARGB32, width, height));
  if (cairo_surface_status(s.get()) != CAIRO_STATUS_SUCCESS)
    throw std::runtime_error(std::string("cairo: cannot make a ") + std::to_string(width) + " x " +
                             std::to_string(height) +
                             " image: " + cairo_status_to_string(cairo_surface_status(s.get())));
  return s;
}

/// A drawing context on `surface`.
inline CairoContext cairo_context(cairo_surface_t* surface) {
  return CairoContext(cairo_create(surface));
}

}  // namespace pinsim
