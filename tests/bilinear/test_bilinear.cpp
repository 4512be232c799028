// The bilinear model: N-mode SVD truncation on a known low-rank tensor (dense and factored
// forms), the model file (round trip, truncation, corruption), coordinate-descent landmark
// fitting from noiseless landmarks, the joint fit, image blendshapes and attribute regression
// on a small bootstrap model (30 identities) from the face model.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include <Eigen/Geometry>

#include "algo/bilinear/bootstrap.hpp"
#include "algo/bilinear/image_fit.hpp"
#include "algo/bilinear/tensor_decomposition.hpp"
#include "algo/facemodel/face_model_format.hpp"
#include "storage/asset_files.hpp"

namespace fb {
namespace {

const FaceModel& face_model() {
  static const FaceModel m = [] {
    auto r = load_face_model();
    EXPECT_TRUE(r.ok());
    return r.ok() ? std::move(*r) : FaceModel{};
  }();
  return m;
}

// A small bootstrap model shared by the fitting tests.
const BilinearModel& small_model() {
  static const BilinearModel m = [] {
    const auto ids = draw_identities(face_model(), 30, 5);
    const FactoredTensor t = bootstrap_tensor(face_model(), ids);
    auto f = mode_factors(t);
    EXPECT_TRUE(f.ok());
    auto tr = truncate(t, *f, 12, 10);
    EXPECT_TRUE(tr.ok());
    return make_bilinear_model(*tr, face_model(), bootstrap_expression_names(face_model()), "{}");
  }();
  return m;
}

// T = C x_2 U x_3 W with random C (rows x 3 x 2), U (8 x 3), W (5 x 2): rank (3, 2).
DataTensor low_rank_tensor(int rows, int identities, int expressions, int r_id, int r_exp) {
  std::mt19937 rng(11);
  std::normal_distribution<double> n(0, 1);
  Eigen::MatrixXd u(identities, r_id), w(expressions, r_exp);
  for (int i = 0; i < u.size(); ++i) u.data()[i] = n(rng);
  for (int i = 0; i < w.size(); ++i) w.data()[i] = n(rng);
  std::vector<Eigen::MatrixXd> core(static_cast<std::size_t>(r_exp), Eigen::MatrixXd(rows, r_id));
  for (auto& c : core)
    for (int i = 0; i < c.size(); ++i) c.data()[i] = n(rng);
  DataTensor t;
  t.rows = rows;
  t.identities = identities;
  t.expressions = expressions;
  t.data.assign(static_cast<std::size_t>(rows) * identities * expressions, 0.0f);
  for (int e = 0; e < expressions; ++e)
    for (int i = 0; i < identities; ++i)
      for (int b = 0; b < r_exp; ++b)
        for (int a = 0; a < r_id; ++a)
          for (int x = 0; x < rows; ++x)
            t.data[(static_cast<std::size_t>(e) * identities + i) * rows + x] +=
                static_cast<float>(core[static_cast<std::size_t>(b)](x, a) * u(i, a) * w(e, b));
  return t;
}

// Reconstruction T~ = C_r x_2 U~ x_3 W~; max abs error against t relative to max |t|.
double relative_reconstruction_error(const DataTensor& t, const TruncatedTensor& tr) {
  double worst = 0, scale = 0;
  for (int e = 0; e < t.expressions; ++e)
    for (int i = 0; i < t.identities; ++i)
      for (int x = 0; x < t.rows; ++x) {
        double v = 0;
        for (int b = 0; b < tr.exp_knobs; ++b)
          for (int a = 0; a < tr.id_knobs; ++a)
            v += tr.core[(static_cast<std::size_t>(b) * tr.id_knobs + a) * t.rows + x] *
                 tr.identity(i, a) * tr.expression(e, b);
        const double truth = t.data[(static_cast<std::size_t>(e) * t.identities + i) * t.rows + x];
        worst = std::max(worst, std::abs(v - truth));
        scale = std::max(scale, std::abs(truth));
      }
  return worst / scale;
}

TEST(Tensor, LowRankTensorIsRecoveredExactlyByTruncation) {
  const DataTensor t = low_rank_tensor(40, 8, 5, 3, 2);
  auto f = mode_factors(t);
  ASSERT_TRUE(f.ok()) << f.error().message;
  // Rank (3, 2): the spectra vanish after the 3rd / 2nd value.
  EXPECT_LT(f->identity_spectrum[3], 1e-5 * f->identity_spectrum[0]);
  EXPECT_LT(f->expression_spectrum[2], 1e-5 * f->expression_spectrum[0]);
  auto exact = truncate(t, *f, 3, 2);
  ASSERT_TRUE(exact.ok());
  EXPECT_LT(relative_reconstruction_error(t, *exact), 1e-5);
  // One knob fewer is visibly not exact.
  auto short_id = truncate(t, *f, 2, 2);
  ASSERT_TRUE(short_id.ok());
  EXPECT_GT(relative_reconstruction_error(t, *short_id), 1e-2);
  // Factor columns are orthonormal.
  EXPECT_LT(
      (exact->identity.transpose() * exact->identity - Eigen::MatrixXd::Identity(3, 3)).norm(),
      1e-9);
  // Knob counts beyond the tensor are refused.
  EXPECT_FALSE(truncate(t, *f, 9, 2).ok());
}

TEST(Tensor, FactoredFormMatchesTheDenseForm) {
  // The same tensor given as basis * coefficients: identical factors and core.
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0, 1);
  FactoredTensor ft;
  ft.rows = 30;
  ft.identities = 6;
  ft.expressions = 4;
  ft.basis.resize(30, 7);
  for (int i = 0; i < ft.basis.size(); ++i) ft.basis.data()[i] = static_cast<float>(n(rng));
  ft.coefficients.resize(7, 24);
  for (int i = 0; i < ft.coefficients.size(); ++i) ft.coefficients.data()[i] = n(rng);
  DataTensor dt;
  dt.rows = 30;
  dt.identities = 6;
  dt.expressions = 4;
  const Eigen::MatrixXf dense = ft.basis * ft.coefficients.cast<float>();
  dt.data.assign(dense.data(), dense.data() + dense.size());
  auto fd = mode_factors(dt);
  auto ff = mode_factors(ft);
  ASSERT_TRUE(fd.ok() && ff.ok());
  EXPECT_LT((fd->identity_spectrum - ff->identity_spectrum).norm(),
            1e-4 * ff->identity_spectrum.norm());
  auto td = truncate(dt, *fd, 4, 3);
  auto tf = truncate(ft, *ff, 4, 3);
  ASSERT_TRUE(td.ok() && tf.ok());
  double worst = 0;
  for (std::size_t k = 0; k < td->core.size(); ++k)
    worst = std::max(worst, static_cast<double>(std::abs(td->core[k] - tf->core[k])));
  EXPECT_LT(worst, 1e-3);
  EXPECT_NEAR(relative_reconstruction_error(dt, *td), relative_reconstruction_error(dt, *tf), 1e-4);
}

TEST(ModelFile, RoundTripAndBadFiles) {
  const BilinearModel& m = small_model();
  const auto bytes = serialize_bilinear_model(m);
  auto back = parse_bilinear_model(bytes);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->core, m.core);
  EXPECT_EQ(back->identity_factors, m.identity_factors);
  EXPECT_EQ(back->expression_names, m.expression_names);
  EXPECT_EQ(back->triangles, m.triangles);
  EXPECT_EQ(back->landmark_vertices, m.landmark_vertices);
  EXPECT_EQ(back->metadata, "{}");

  auto truncated = parse_bilinear_model(std::span(bytes).first(bytes.size() / 2));
  ASSERT_FALSE(truncated.ok());
  EXPECT_NE(truncated.error().message.find("truncated"), std::string::npos)
      << truncated.error().message;
  EXPECT_FALSE(parse_bilinear_model(std::span(bytes).first(20)).ok());
  auto corrupt = bytes;
  corrupt[corrupt.size() / 3] ^= std::byte{0x40};
  auto c = parse_bilinear_model(corrupt);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().message.find("checksum"), std::string::npos) << c.error().message;
  auto magic = bytes;
  magic[0] = std::byte{'X'};
  auto mg = parse_bilinear_model(magic);
  ASSERT_FALSE(mg.ok());
  EXPECT_NE(mg.error().message.find("magic"), std::string::npos);
  EXPECT_NE(mg.error().message.find("facebooth model build"), std::string::npos);
}

// Found by review while writing bilinear_model_fuzz: each count may be up to 2^26, so the core's
// 3 V Kid Kexp floats passed 2^64 and the size check compared a wrapped number with the file.
TEST(ModelFile, CoreLargerThanTheFileIsRefusedBeforeItsSizeCanWrap) {
  BilinearModel m;
  m.vertex_count = 4;
  m.face_vertex_count = 4;
  m.id_knobs = m.exp_knobs = m.identity_count = m.expression_count = 1;
  m.core.assign(12, 1.0f);
  m.identity_factors = m.expression_factors = m.identity_spectrum = m.expression_spectrum = {1};
  m.expression_names = {"neutral"};
  m.triangles = {0, 1, 2};
  auto bytes = serialize_bilinear_model(m);
  ASSERT_TRUE(parse_bilinear_model(bytes).ok());
  auto put = [&](std::size_t at, std::uint32_t v) { std::memcpy(bytes.data() + at, &v, 4); };
  put(24, 1u << 25);                                          // vertices
  for (std::size_t at : {32, 36, 40, 44}) put(at, 1u << 20);  // knobs and counts
  const std::uint32_t crc = fbfm::crc32(std::span<const std::byte>(bytes).subspan(16));
  std::memcpy(bytes.data() + 12, &crc, 4);
  auto r = parse_bilinear_model(bytes);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("larger than the file"), std::string::npos) << r.error().message;
}

struct Truth {
  WeakPerspectivePose pose;
  std::vector<float> w_id, w_exp, mesh;
};

Truth make_truth(int identity, int expression, double yaw_deg, double pitch_deg) {
  const BilinearModel& m = small_model();
  Truth t;
  t.w_id.assign(m.identity_row(identity).begin(), m.identity_row(identity).end());
  t.w_exp.assign(m.expression_row(expression).begin(), m.expression_row(expression).end());
  t.mesh.resize(static_cast<std::size_t>(m.coordinate_count()));
  m.evaluate(t.w_id, t.w_exp, t.mesh);
  t.pose.scale = 2.3;  // px per mm
  t.pose.rotation = (Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()) *
                     Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitY()) *
                     Eigen::AngleAxisd(pitch_deg * M_PI / 180, Eigen::Vector3d::UnitX()) *
                     Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitZ()))
                        .toRotationMatrix();
  t.pose.translation = {320, 240};
  return t;
}

ImageLandmarks project(const Truth& t) {
  const BilinearModel& m = small_model();
  ImageLandmarks l;
  for (int k = 0; k < 68; ++k) {
    const auto v = m.landmark_vertices[static_cast<std::size_t>(k)];
    l.points[static_cast<std::size_t>(k)] =
        t.pose.project({t.mesh[3 * v], t.mesh[3 * v + 1], t.mesh[3 * v + 2]});
    l.valid[static_cast<std::size_t>(k)] = true;
  }
  return l;
}

double landmark_error_mm(const std::vector<float>& w_id, const std::vector<float>& w_exp,
                         const std::vector<float>& truth) {
  const BilinearModel& m = small_model();
  std::vector<float> mesh(static_cast<std::size_t>(m.coordinate_count()));
  m.evaluate(w_id, w_exp, mesh);
  double s = 0;
  for (auto v : m.landmark_vertices)
    s += Eigen::Vector3d(mesh[3 * v] - truth[3 * v], mesh[3 * v + 1] - truth[3 * v + 1],
                         mesh[3 * v + 2] - truth[3 * v + 2])
             .norm();
  return s / 68;
}

// Weak perspective observes s * mesh, not the mesh's absolute size (w -> c w, s -> s / c leaves
// the image unchanged; only the prior picks c). So shapes are compared as s R v in pixels,
// all three coordinates (depth included).
double scaled_landmark_error_px(const WeakPerspectivePose& pose, const std::vector<float>& w_id,
                                const std::vector<float>& w_exp, const Truth& t) {
  const BilinearModel& m = small_model();
  std::vector<float> mesh(static_cast<std::size_t>(m.coordinate_count()));
  m.evaluate(w_id, w_exp, mesh);
  double s = 0;
  for (auto v : m.landmark_vertices) {
    const Eigen::Vector3d a(mesh[3 * v], mesh[3 * v + 1], mesh[3 * v + 2]);
    const Eigen::Vector3d b(t.mesh[3 * v], t.mesh[3 * v + 1], t.mesh[3 * v + 2]);
    s += (pose.scale * pose.rotation * a - t.pose.scale * t.pose.rotation * b).norm();
  }
  return s / 68;
}

double angle_deg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle() * 180 / M_PI;
}

TEST(LandmarkFit, CoordinateDescentRecoversPoseAndWeightsFromNoiselessLandmarks) {
  const Truth t = make_truth(4, 9, 20, -10);
  LandmarkFitOptions o;
  o.identity_prior = 1e-4;
  o.expression_prior = 1e-4;
  o.iterations = 400;
  auto fit = fit_landmarks(small_model(), project(t), o);
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  const double shape_px = scaled_landmark_error_px(fit->pose, fit->w_id, fit->w_exp, t);
  std::printf("error %.4f px, scale %.4f, angle %.4f deg, landmarks %.4f mm, %.4f px in 3D\n",
              fit->mean_error_px, fit->pose.scale, angle_deg(fit->pose.rotation, t.pose.rotation),
              landmark_error_mm(fit->w_id, fit->w_exp, t.mesh), shape_px);
  EXPECT_LT(fit->mean_error_px, 0.01);
  EXPECT_LT(angle_deg(fit->pose.rotation, t.pose.rotation), 0.1);
  EXPECT_NEAR(fit->pose.scale, t.pose.scale, 0.01 * t.pose.scale);  // the prior picks the size
  EXPECT_LT((fit->pose.translation - t.pose.translation).norm(), 0.1);
  EXPECT_LT(shape_px, 0.05);
  // The weights themselves (up to the bilinear scale trade-off w_id * c, w_exp / c).
  Eigen::VectorXf fid = Eigen::Map<const Eigen::VectorXf>(fit->w_id.data(), 12);
  Eigen::VectorXf tid = Eigen::Map<const Eigen::VectorXf>(t.w_id.data(), 12);
  Eigen::VectorXf fex = Eigen::Map<const Eigen::VectorXf>(fit->w_exp.data(), 10);
  Eigen::VectorXf tex = Eigen::Map<const Eigen::VectorXf>(t.w_exp.data(), 10);
  const float c_id = fid.dot(tid) / fid.squaredNorm();
  const float c_exp = fex.dot(tex) / fex.squaredNorm();
  EXPECT_LT((c_id * fid - tid).norm() / tid.norm(), 0.02);
  EXPECT_LT((c_exp * fex - tex).norm() / tex.norm(), 0.02);
}

TEST(LandmarkFit, JointFitSharesOneIdentity) {
  std::vector<Truth> truths = {make_truth(7, 0, 0, 0), make_truth(7, 3, 25, 5),
                               make_truth(7, 20, -20, -8)};
  std::vector<ImageLandmarks> images;
  for (const auto& t : truths) images.push_back(project(t));
  LandmarkFitOptions o;
  o.identity_prior = 1e-3;
  o.expression_prior = 1e-3;
  auto joint = fit_landmarks_joint(small_model(), images, o, 3);
  ASSERT_TRUE(joint.ok()) << joint.error().message;
  ASSERT_EQ(joint->images.size(), 3u);
  EXPECT_LT(joint->mean_error_px, 0.3);
  for (std::size_t i = 0; i < truths.size(); ++i) {
    const double px = scaled_landmark_error_px(joint->images[i].pose, joint->w_id,
                                               joint->images[i].w_exp, truths[i]);
    std::printf("image %zu: %.3f px, %.3f px in 3D\n", i, joint->images[i].mean_error_px, px);
    EXPECT_LT(px, 0.5);
  }
}

TEST(ImageBlendshapes, ReproduceTheTrainingSubjectsExpressions) {
  // Eq. 17 with a training identity's row gives back that subject's expressions up to the
  // truncation error; with all knobs it is exact.
  const auto ids = draw_identities(face_model(), 12, 9);
  const FactoredTensor t = bootstrap_tensor(face_model(), ids);
  auto f = mode_factors(t);
  ASSERT_TRUE(f.ok());
  auto tr = truncate(t, *f, 12, 54);
  ASSERT_TRUE(tr.ok());
  const BilinearModel m =
      make_bilinear_model(*tr, face_model(), bootstrap_expression_names(face_model()), "{}");
  const auto shapes = image_blendshapes(m, m.identity_row(5));
  ASSERT_EQ(shapes.size(), 54u);
  std::vector<float> truth(static_cast<std::size_t>(m.coordinate_count()));
  std::vector<float> w(static_cast<std::size_t>(face_model().fitting_expression_count), 0.0f);
  w[10] = 1.0f;  // expression 11 of the model = fitting shape 10
  face_model().evaluate(ids[5], w, truth);
  double worst = 0;
  for (std::size_t k = 0; k < truth.size(); ++k)
    worst = std::max(worst, static_cast<double>(std::abs(shapes[11][k] - truth[k])));
  EXPECT_LT(worst, 0.01);  // mm
}

TEST(Attributes, RegressionChangesTheRequestedAttribute) {
  const BilinearModel& m = small_model();
  const auto attributes = default_attributes();
  auto reg = fit_attribute_regression(m, attributes);
  ASSERT_TRUE(reg.ok()) << reg.error().message;
  std::vector<float> mesh(static_cast<std::size_t>(m.coordinate_count()));
  const auto w_id = m.identity_row(3);
  m.evaluate(w_id, m.expression_row(0), mesh);
  const auto before = measure_attributes(mesh, m.landmark_vertices, attributes);
  std::vector<double> change(attributes.size(), 0.0);
  change[2] = 4.0;  // mouth width +4 mm
  const auto w2 = apply_attribute_change(*reg, w_id, change);
  m.evaluate(w2, m.expression_row(0), mesh);
  const auto after = measure_attributes(mesh, m.landmark_vertices, attributes);
  std::printf("mouth width %.2f -> %.2f mm, face width %.2f -> %.2f mm\n", before[2], after[2],
              before[1], after[1]);
  EXPECT_NEAR(after[2] - before[2], 4.0, 1.0);
  EXPECT_NEAR(after[1] - before[1], 0.0, 1.0);  // the others are held
}

}  // namespace
}  // namespace fb
