// A printed checkerboard on a flat plate, as `camera calibrate --board 9x6:25mm` describes it.
//
// Board frame (mm): origin at the first inner corner, x along a row of inner corners (`cols`
// of them), y along a column (`rows`), z = 0 on the printed face, +z into the plate (away from
// a camera that sees the print). The outer square at x, y in [-square, 0] is black, which
// fixes the order of the detected corners (the pattern is not symmetric under a half turn when
// cols + rows is odd). The plate carries a white margin of one square around the squares.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "algo/core/result.hpp"

namespace fb {

struct BoardSpec {
  int cols = 9;  // inner corners along x
  int rows = 6;  // inner corners along y
  double square_mm = 25.0;
  double margin_mm = 25.0;  // white border beyond the outer squares

  int corner_count() const { return cols * rows; }
  // Inner corner j (row-major, j = col + cols * row) in the board frame.
  Eigen::Vector3d corner(int j) const;
  // The plate's outline, 4 points in the board frame, in order around it.
  std::vector<Eigen::Vector3d> plate_outline() const;
  // Plate width/height in mm.
  double plate_width_mm() const { return (cols + 1) * square_mm + 2.0 * margin_mm; }
  double plate_height_mm() const { return (rows + 1) * square_mm + 2.0 * margin_mm; }
  // 0 = black square, 1 = white square or margin, -1 = off the plate, at board point (x, y).
  int print_at(double x, double y) const;
  std::string to_string() const;  // "9x6:25mm"
};

// Parses "COLSxROWS:SIZEmm" (inner corners and square size), e.g. "9x6:25mm". Needs at least
// 3x3 corners, cols + rows odd (so the corner order is unambiguous) and 5..200 mm squares.
Result<BoardSpec> parse_board_spec(std::string_view text);

}  // namespace fb
