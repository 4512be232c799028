// Guide expression recipes: the committed data parses, references existing shapes, and bad
// recipe text gives clear errors.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "algo/guide/guide_expressions.hpp"
#include "storage/asset_files.hpp"
#include "tests/common/test_face_model.hpp"
#include "tests/fuzz/regression_input.hpp"

namespace fb {
namespace {

std::string read_guide_file() {
  std::ifstream in(std::string(FB_DATA_DIR) + "/guide_expressions.json");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(Guide, CommittedRecipesParseAndReferenceModelShapes) {
  auto guide = parse_guide_expressions(read_guide_file());
  ASSERT_TRUE(guide.ok()) << guide.error().message;
  ASSERT_EQ(guide->expressions.size(), 20u);
  const char* names[] = {"neutral",     "mouth_stretch", "smile",         "brow_lower",
                         "brow_raiser", "anger",         "jaw_left",      "jaw_right",
                         "jaw_forward", "mouth_left",    "mouth_right",   "dimpler",
                         "chin_raiser", "lip_pucker",    "lip_funneler",  "sadness",
                         "lip_roll",    "grin",          "cheek_blowing", "eyes_closed"};
  for (int i = 0; i < 20; ++i) {
    EXPECT_EQ(guide->expressions[i].id, i);
    EXPECT_EQ(guide->expressions[i].name, names[i]);
    if (i > 0) {
      EXPECT_FALSE(guide->expressions[i].weights.empty()) << names[i];
    }
  }
  auto ok = validate_guide(*guide, test::face_model());
  EXPECT_TRUE(ok.ok()) << (ok.ok() ? "" : ok.error().message);
  // Every non-neutral guide mesh differs from G0; G0 is the model's mean face.
  auto g0 = guide_mesh(guide->expressions[0], test::face_model());
  ASSERT_TRUE(g0.ok());
  for (int i = 1; i < 20; ++i) {
    auto gi = guide_mesh(guide->expressions[i], test::face_model());
    ASSERT_TRUE(gi.ok());
    double max_move = 0;
    for (std::size_t k = 0; k < gi->size(); ++k)
      max_move = std::max<double>(max_move, std::abs((*gi)[k] - (*g0)[k]));
    EXPECT_GT(max_move, 2.0) << names[i];  // a visible expression (mm)
  }
  EXPECT_EQ(guide->find("smile"), 2);
  EXPECT_EQ(guide->find("nope"), -1);
}

// Found while writing guide_fuzz (the target aborts on it): nlohmann's value() throws when the
// member has another type, and "format": 1 escaped the parser as an exception (the daemon and
// the CLI would terminate on such a guide file). An id of 2^32 read as 0.
TEST(Guide, WrongTypesAndWideIdsAreErrorsNotExceptions) {
  auto format = parse_guide_expressions(test::fuzz_regression("guide_fuzz", "format-not-a-string"));
  ASSERT_FALSE(format.ok());
  EXPECT_NE(format.error().message.find("format"), std::string::npos) << format.error().message;
  EXPECT_FALSE(parse_guide_expressions(
      R"({"format":"facebooth-guide-expressions","version":"1","expressions":[]})"));
  auto id = parse_guide_expressions(
      R"({"format":"facebooth-guide-expressions","version":1,"expressions":[)"
      R"({"id":4294967296,"name":"neutral","weights":{}}]})");
  ASSERT_FALSE(id.ok());
  EXPECT_NE(id.error().message.find("0..1000"), std::string::npos) << id.error().message;
}

TEST(Guide, BadTextGivesClearErrors) {
  auto expect_error = [](const std::string& text, const std::string& needle) {
    auto r = parse_guide_expressions(text);
    ASSERT_FALSE(r.ok()) << text;
    EXPECT_NE(r.error().message.find(needle), std::string::npos) << r.error().message;
  };
  expect_error("{", "not valid JSON");
  expect_error(R"({"format":"other","version":1,"expressions":[]})", "format");
  expect_error(R"({"format":"facebooth-guide-expressions","version":2,"expressions":[]})",
               "version");
  const std::string head = R"({"format":"facebooth-guide-expressions","version":1,"expressions":[)";
  expect_error(
      head + R"({"id":0,"name":"neutral","weights":{}},{"id":2,"name":"a","weights":{}}]})",
      "missing id 1");
  expect_error(head + R"({"id":0,"name":"neutral","weights":{"jawOpen":0.5}}]})", "neutral");
  expect_error(
      head +
          R"({"id":0,"name":"neutral","weights":{}},{"id":1,"name":"a","weights":{"jawOpen":1.5}}]})",
      "[0, 1]");
  expect_error(
      head + R"({"id":0,"name":"neutral","weights":{}},{"id":1,"name":"neutral","weights":{}}]})",
      "duplicate");
  auto unknown = parse_guide_expressions(
      head +
      R"({"id":0,"name":"neutral","weights":{}},{"id":1,"name":"a","weights":{"notAShape":0.5}}]})");
  ASSERT_TRUE(unknown.ok());
  auto v = validate_guide(*unknown, test::face_model());
  ASSERT_FALSE(v.ok());
  EXPECT_NE(v.error().message.find("notAShape"), std::string::npos);
}

}  // namespace
}  // namespace fb
