// The rigging input of a stored session (host/cli/rig_session.cpp): a session with missing fitted
// expressions is refused with the list of what is missing, unless allow_missing, in which case
// it is rigged from what is there; a session without a fitted neutral is always refused.
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include "host/cli/rig_session.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {
namespace {

struct TempDir {
  std::filesystem::path path;
  TempDir() {
    path = std::filesystem::temp_directory_path() /
           ("fb-rig-session-" + std::to_string(std::random_device{}()));
    std::filesystem::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

TEST(RigSession, MissingExpressionsAreRefusedOrRiggedFromWhatIsThere) {
  auto model = load_face_model();
  ASSERT_TRUE(model.ok());
  auto guide = load_guide_expressions(*model);
  ASSERT_TRUE(guide.ok()) << guide.error().message;
  TempDir dir;
  auto store = SessionStore::open(dir.path);
  ASSERT_TRUE(store.ok()) << store.error().message;
  auto subject = store->add_subject("tester");
  ASSERT_TRUE(subject.ok());
  std::vector<std::string> names;
  for (const auto& g : guide->expressions) names.push_back(g.name);
  auto session = store->create_session(*subject, names);
  ASSERT_TRUE(session.ok());
  // Fitted meshes for every capture but 2 (smile) and 7.
  for (const auto& g : guide->expressions) {
    if (g.id == 2 || g.id == 7) continue;
    auto w = guide_weights(g, *model);
    ASSERT_TRUE(w.ok());
    MeshData mesh;
    mesh.positions.resize(static_cast<std::size_t>(model->vertex_count) * 3);
    model->evaluate({}, *w, mesh.positions);
    mesh.triangles = model->triangles;
    ASSERT_TRUE(store
                    ->add_mesh(*session, g.id, g.id == 0 ? MeshRole::kNeutral : MeshRole::kFitted,
                               g.name, mesh)
                    .ok());
  }
  auto refused = load_session_examples(*store, *session, *model, *guide, false);
  ASSERT_FALSE(refused.ok());
  const std::string& msg = refused.error().message;
  EXPECT_NE(msg.find("missing fitted meshes for 2 of 20"), std::string::npos) << msg;
  EXPECT_NE(msg.find("smile (capture 2)"), std::string::npos) << msg;
  EXPECT_NE(msg.find("--allow-missing"), std::string::npos) << msg;

  auto partial = load_session_examples(*store, *session, *model, *guide, true);
  ASSERT_TRUE(partial.ok()) << partial.error().message;
  EXPECT_EQ(partial->meshes.size(), 18u);
  EXPECT_EQ(partial->missing.size(), 2u);
  EXPECT_EQ(partial->names.front(), "neutral");
  // And it rigs: the generic model's own expressions are reproduced.
  std::vector<std::vector<float>> generic;
  RigInput input = generic_rig_input(*model, generic);
  for (const auto& m : partial->meshes) input.examples.emplace_back(m);
  input.example_weights = partial->weights;
  RigOptions o;
  o.rounds = 1;
  auto rig = rig_subject(input, o);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  EXPECT_LT(rig->round_residual_mm.back(), 0.2);

  // No neutral: always refused.
  auto other = store->create_session(*subject, names);
  ASSERT_TRUE(other.ok());
  auto none = load_session_examples(*store, *other, *model, *guide, true);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message.find("no fitted neutral"), std::string::npos);
}

}  // namespace
}  // namespace fb::cli
