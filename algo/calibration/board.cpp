#include "algo/calibration/board.hpp"

#include <charconv>
#include <cmath>

namespace fb {

Eigen::Vector3d BoardSpec::corner(int j) const {
  return {(j % cols) * square_mm, (j / cols) * square_mm, 0.0};
}

std::vector<Eigen::Vector3d> BoardSpec::plate_outline() const {
  const double x0 = -square_mm - margin_mm, y0 = -square_mm - margin_mm;
  const double x1 = cols * square_mm + margin_mm, y1 = rows * square_mm + margin_mm;
  return {{x0, y0, 0.0}, {x1, y0, 0.0}, {x1, y1, 0.0}, {x0, y1, 0.0}};
}

int BoardSpec::print_at(double x, double y) const {
  const double x0 = -square_mm - margin_mm, y0 = -square_mm - margin_mm;
  const double x1 = cols * square_mm + margin_mm, y1 = rows * square_mm + margin_mm;
  if (x < x0 || y < y0 || x > x1 || y > y1) return -1;
  if (x < -square_mm || y < -square_mm || x >= cols * square_mm || y >= rows * square_mm) return 1;
  const auto i = static_cast<long>(std::floor(x / square_mm));
  const auto k = static_cast<long>(std::floor(y / square_mm));
  return ((i + k) & 1) == 0 ? 0 : 1;
}

std::string BoardSpec::to_string() const {
  char size[32];
  std::snprintf(size, sizeof size, "%g", square_mm);
  return std::to_string(cols) + "x" + std::to_string(rows) + ":" + size + "mm";
}

Result<BoardSpec> parse_board_spec(std::string_view text) {
  const auto usage = [&](const std::string& why) {
    return fail("bad board '" + std::string(text) + "': " + why +
                "; expected COLSxROWS:SIZEmm with the inner corners and the square size, e.g. "
                "9x6:25mm");
  };
  const auto x = text.find('x');
  const auto colon = text.find(':');
  if (x == std::string_view::npos || colon == std::string_view::npos || colon < x) {
    return usage("missing 'x' or ':'");
  }
  BoardSpec spec;
  auto parse_int = [](std::string_view s, int& out) {
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
    return ec == std::errc() && end == s.data() + s.size();
  };
  if (!parse_int(text.substr(0, x), spec.cols) ||
      !parse_int(text.substr(x + 1, colon - x - 1), spec.rows)) {
    return usage("the corner counts are not whole numbers");
  }
  std::string_view size = text.substr(colon + 1);
  if (size.size() > 2 && size.substr(size.size() - 2) == "mm") size.remove_suffix(2);
  const auto [end, ec] = std::from_chars(size.data(), size.data() + size.size(), spec.square_mm);
  if (ec != std::errc() || end != size.data() + size.size()) {
    return usage("the square size is not a number of millimetres");
  }
  if (spec.cols < 3 || spec.rows < 3 || spec.cols > 30 || spec.rows > 30) {
    return usage("between 3 and 30 inner corners per side are supported");
  }
  if ((spec.cols + spec.rows) % 2 == 0) {
    return usage("cols + rows must be odd (e.g. 9x6), or the board's two ends look alike");
  }
  if (!(spec.square_mm >= 5.0 && spec.square_mm <= 200.0)) {
    return usage("the square size must be 5..200 mm");
  }
  spec.margin_mm = spec.square_mm;
  return spec;
}

}  // namespace fb
