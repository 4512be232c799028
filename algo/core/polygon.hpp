// Whether a point is inside a polygon (even-odd rule): the face regions of image transfer and
// the photo's mouth, and the lab's scoring masks.
#pragma once

#include <cstddef>

namespace fb {

// `polygon`: indexable 2D points (Eigen vectors, float or double) in order, closed implicitly.
// The arithmetic is the points' own scalar type, x and y converted to it where they meet.
template <class Polygon, class Scalar>
bool inside_polygon(const Polygon& polygon, Scalar x, Scalar y) {
  bool in = false;
  for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const auto& a = polygon[i];
    const auto& b = polygon[j];
    if ((a.y() > y) != (b.y() > y) && x < (b.x() - a.x()) * (y - a.y()) / (b.y() - a.y()) + a.x())
      in = !in;
  }
  return in;
}

}  // namespace fb
