// The normal matrix of the Laplacian refinement (FaceWarehouse 3.2.2, E2), factorized once and
// shared by every Gauss-Newton step of a fit and by every expression fit of a subject:
//
//   A = w_lap L_F^T L_F + w_pos P_F + eps I
//
// over the free vertices F = the model's fitting vertices plus `margin_rings` rings of
// neighbours. L is the cotangent Laplacian of a reference mesh (the start of a neutral fit, the
// fitted neutral for a subject's expressions), L_F its columns of F, P_F selects the fitting
// vertices (each has a position term; one without a depth correspondence in a step is pulled
// to where it is, which vanishes at the fixed point), and eps removes the null space. Vertices
// outside F have no data term; they keep the start mesh and enter the right-hand side through
// L_C x_C. Landmarks are not in A (their vertex slides with the contour rule and changes per
// fit): their pull enters the right-hand side lagged, w_fea (goal - x), which has the same
// fixed point and contracts because w_fea is small against A's diagonal there (only vertices
// with a position term take one).
//
// Sharing one matrix across the 20 captures of a subject is what makes an expression fit cost
// back-substitutions instead of a factorization.
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Sparse>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"

namespace fb {

struct RefineSystemOptions {
  double w_pos = 1.0;
  double w_lap = 1.0;
  int margin_rings = 2;  // free vertices around the fitting region
  double anchor = 1e-4;  // eps: pull towards the start mesh of each fit
  bool operator==(const RefineSystemOptions&) const = default;
};

class RefineSystem {
 public:
  using Points = Eigen::Matrix<double, Eigen::Dynamic, 3>;  // one vertex per row

  // `reference`: vertex_count x 3, any rigid frame (cotangents are rigid-invariant).
  static Result<RefineSystem> create(const FaceModel& model, const Points& reference,
                                     const RefineSystemOptions& options);
  RefineSystem(RefineSystem&&) noexcept;
  RefineSystem& operator=(RefineSystem&&) noexcept;
  ~RefineSystem();

  const RefineSystemOptions& options() const;
  const Eigen::SparseMatrix<double>& laplacian() const;  // n x n, of the reference
  const std::vector<int>& free_vertices() const;         // F, ascending
  // Index of vertex v in F, or -1 when v is held at the start mesh.
  int free_index(int v) const;
  // Whether vertex v has a position term in A.
  bool has_position_term(int v) const;

  // x_F = A^-1 rhs for the three coordinates at once (rhs and result |F| x 3).
  void solve(Points& rhs_in_out) const;
  // w_lap L_F^T (target - L_C x_C): the Laplacian part of the right-hand side, for a target
  // Laplacian `target` (n x 3) with the held vertices at `held` (n x 3, only C rows read).
  void laplacian_rhs(const Points& target, const Points& held, Points& out) const;

  double factorization_ms() const;
  std::size_t factor_nonzeros() const;

 private:
  struct State;
  explicit RefineSystem(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace fb
