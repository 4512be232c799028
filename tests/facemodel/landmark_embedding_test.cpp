// dlib's landmark convention on the face model: the CSV form and the learning from hits.
#include <gtest/gtest.h>

#include "algo/facemodel/landmark_embedding.hpp"

namespace fb {
namespace {

// 100 vertices on a line along x, 1 mm apart; landmark l marks vertex l (the model's own).
FaceModel line_model() {
  FaceModel m;
  m.vertex_count = 100;
  m.face_vertex_count = 90;  // 90-99: the back of the head, never a landmark
  for (int v = 0; v < 100; ++v) m.neutral.insert(m.neutral.end(), {static_cast<float>(v), 0, 0});
  for (int l = 0; l < 68; ++l) m.landmark_vertices[static_cast<std::size_t>(l)] = l;
  return m;
}

TEST(LandmarkEmbedding, LearnsTheMedianPointAndLeavesTheContourAndSparseLandmarks) {
  const FaceModel m = line_model();
  std::array<std::vector<std::uint32_t>, 68> hits;
  hits[20] = {30, 31, 32, 33, 89, 31, 32};  // one stray hit far away: the median ignores it
  hits[40] = {50, 51};                      // too few hits: the model's vertex stays
  hits[5] = {70, 70, 70, 70, 70, 70};       // contour: the fit slides it, never moved
  hits[67] = {95, 95, 95, 95, 95};          // outside the face region: snapped into it
  const LandmarkEmbedding e = learn_landmark_embedding(m, hits);
  EXPECT_EQ(e.vertices[20], 32u);
  EXPECT_EQ(e.vertices[40], 40u);
  EXPECT_EQ(e.vertices[5], 5u);
  EXPECT_EQ(e.vertices[67], 89u);
  EXPECT_EQ(e.vertices[50], 50u);
}

TEST(LandmarkEmbedding, CsvRoundTripsAndBadFilesSayWhatIsWrong) {
  const FaceModel m = line_model();
  LandmarkEmbedding e = model_landmark_embedding(m);
  e.vertices[30] = 77;
  const std::string text = format_landmark_embedding(e, "made by a test\nsecond line");
  EXPECT_EQ(text.rfind("# made by a test\n# second line\nlandmark,vertex\n0,0\n", 0), 0u);
  auto back = parse_landmark_embedding(text, m);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->vertices, e.vertices);

  auto no_header = parse_landmark_embedding("0,1\n", m);
  ASSERT_FALSE(no_header.ok());
  EXPECT_NE(no_header.error().message.find("header 'landmark,vertex'"), std::string::npos);

  std::string missing = "landmark,vertex\n";
  for (int l = 0; l < 67; ++l) missing += std::to_string(l) + "," + std::to_string(l) + "\n";
  auto short_file = parse_landmark_embedding(missing, m);
  ASSERT_FALSE(short_file.ok());
  EXPECT_NE(short_file.error().message.find("landmark 67 has no row"), std::string::npos);

  std::string outside = text;
  outside.replace(outside.find("\n30,77\n"), 7, "\n30,100\n");
  auto bad_vertex = parse_landmark_embedding(outside, m);
  ASSERT_FALSE(bad_vertex.ok());
  EXPECT_NE(bad_vertex.error().message.find("100 vertices"), std::string::npos);
}

TEST(LandmarkEmbedding, PerExpressionEntriesOverrideTheDefaultAndRoundTrip) {
  const FaceModel m = line_model();
  std::map<std::string, LandmarkHits> hits;
  // Inner lip 62: on 30 when the mouth is closed, on 60 when it opens; brow 20 the same in both.
  hits["neutral"][62] = {30, 30, 31, 30, 29, 30};
  hits["mouth_stretch"][62] = {60, 60, 61, 60, 59, 60};
  hits["neutral"][20] = {25, 25, 25, 25, 25};
  hits["mouth_stretch"][20] = {25, 25, 25, 25, 25};
  hits["smile"][62] = {44, 44};  // too few of its own: the pooled vertex, no entry
  const LandmarkEmbedding e = learn_landmark_embedding(m, hits);
  EXPECT_EQ(e.vertices[20], 25u);
  EXPECT_EQ(e.for_expression("neutral")[62], 30u);
  EXPECT_EQ(e.for_expression("mouth_stretch")[62], 60u);
  EXPECT_EQ(e.for_expression("mouth_stretch")[20], 25u);
  EXPECT_EQ(e.by_expression.count("smile"), 0u);
  EXPECT_EQ(&e.for_expression("smile"), &e.vertices);
  EXPECT_EQ(&e.for_expression(""), &e.vertices);
  EXPECT_NE(e.vertices[62], 60u);  // the pooled median lies between the two

  const std::string text = format_landmark_embedding(e, "per expression");
  EXPECT_NE(text.find("landmark,vertex,expression\n"), std::string::npos);
  EXPECT_NE(text.find("\n62,60,mouth_stretch\n"), std::string::npos);
  EXPECT_EQ(text.find(",mouth_stretch\n20,"), std::string::npos);  // same as the default: no row
  auto back = parse_landmark_embedding(text, m);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->vertices, e.vertices);
  EXPECT_EQ(back->by_expression, e.by_expression);

  auto empty_name = parse_landmark_embedding(text + "5,5,\n", m);
  ASSERT_FALSE(empty_name.ok());
  EXPECT_NE(empty_name.error().message.find("'5,5,'"), std::string::npos);
}

}  // namespace
}  // namespace fb
