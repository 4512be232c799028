// Small mesh helpers shared by the fitting steps (internal to algo/fitting).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Sparse>

namespace fb::fitting_detail {

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3>;  // one vertex per row

// Packs 3 * n interleaved floats into an n x 3 matrix and back.
Points to_points(std::span<const float> xyz);
void from_points(const Points& p, std::vector<float>& xyz);

// Area-weighted vertex normals (unit; zero for isolated vertices). OBJ winding: counter-
// clockwise seen from outside, so normals point out of the head.
Points vertex_normals(const Points& v, std::span<const std::uint32_t> triangles);

// Cotangent Laplacian (L x)_i = sum_j w_ij (x_i - x_j), w_ij = (cot a + cot b) / 2 over the two
// triangles sharing edge ij (Meyer et al.). Cotangents are clamped to [-10, 10] so slivers
// cannot dominate.
Eigen::SparseMatrix<double> cotangent_laplacian(const Points& v,
                                                std::span<const std::uint32_t> triangles);

// 2D convex hull (Andrew's monotone chain); returns indices into `points`, counter-clockwise.
std::vector<int> convex_hull(const std::vector<Eigen::Vector2d>& points);

}  // namespace fb::fitting_detail
