#include "aff_parser.h"

#include "hand_scene.h"
#include "support/log_capture.h"
#include "support/timing.h"
#include "test_paths.h"

#include <afr/common/error.h>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <numbers>

namespace afr::aff {
namespace {

class HandSceneTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::filesystem::path(test::fresh_temp_dir("aff-parser"));
    scene_ = new Scene(parse_aff_file(test::write_hand_scene(*dir_)));
  }
  static void TearDownTestSuite() {
    std::filesystem::remove_all(*dir_);
    delete scene_;
    delete dir_;
  }
  static std::filesystem::path* dir_;
  static Scene* scene_;
};
std::filesystem::path* HandSceneTest::dir_ = nullptr;
Scene* HandSceneTest::scene_ = nullptr;

TEST_F(HandSceneTest, ReadsTheSceneLevelDirectives) {
  const Scene& s = *scene_;
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
  ASSERT_TRUE(s.view);
  EXPECT_EQ(s.view->from, glm::dvec3(0, 1, 5));
  EXPECT_EQ(s.view->at, glm::dvec3(0, 1, 0));
  EXPECT_EQ(s.view->angle, 45.0);
  EXPECT_EQ(s.view->hither, 1.0);  // below 1e-4: replaced by 1
  EXPECT_EQ(s.view->width, 320);
  EXPECT_EQ(s.view->height, 240);
  EXPECT_EQ(s.background, glm::dvec3(0.1, 0.2, 0.3));
  EXPECT_EQ(s.ambient, glm::dvec3(0.5));
  ASSERT_TRUE(s.animation);
  EXPECT_EQ(s.animation->frames, 21);
  EXPECT_DOUBLE_EQ(s.animation->frame_time(20), 2.0);
  EXPECT_DOUBLE_EQ(s.animation->frame_time(1), 0.1);
  ASSERT_EQ(s.lights.size(), 3u);
  EXPECT_EQ(s.lights[0].color, glm::dvec3(1.0));  // colour omitted: white
  EXPECT_EQ(s.lights[1].position, glm::dvec3(4, 5, 6));
  EXPECT_EQ(s.lights[1].color, glm::dvec3(0.5, 0.25, 1));
  EXPECT_EQ(s.lights[2].name, "lamp");
  EXPECT_EQ(s.lights[2].position, glm::dvec3(0, 3, 0));
}

TEST_F(HandSceneTest, CountsEveryTriangleOfTheExpandedScene) {
  EXPECT_EQ(scene_->triangle_count(), test::kHandSceneTriangles);
}

TEST_F(HandSceneTest, MaterialsFollowParseOrderAndSurviveTheEndOfAnInclude) {
  const Scene& s = *scene_;
  const Node& root = s.nodes[0];
  // p uses the f material in fm form: diffuse Kd * RGB, specular Ks, no ambient.
  const Material& f = s.materials[size_t(root.meshes[0].material)];
  EXPECT_EQ(f.diffuse, glm::dvec3(0.8, 0.4, 0.2));
  EXPECT_EQ(f.specular, glm::dvec3(0.3));
  EXPECT_EQ(f.ambient, glm::dvec3(0.0));
  EXPECT_EQ(f.shine, 20.0);
  EXPECT_EQ(f.ior, 1.0);
  EXPECT_TRUE(f.texture.empty());
  // The spinner's mesh comes after `i 0 part.aff`, whose fm it inherits.
  const Node& spinner = s.nodes[2];
  ASSERT_EQ(spinner.name, "spinner");
  EXPECT_EQ(s.materials[size_t(spinner.meshes[0].material)].diffuse, glm::dvec3(0.9));
  // Textures: checker.ppm from TextureFiles/, gray.ppm from the fallback next to the .aff.
  const Node& xs = s.nodes[1];
  const Material& gray = s.materials[size_t(xs.meshes[0].material)];
  EXPECT_EQ(gray.texture.filename(), "gray.ppm");
  EXPECT_EQ(gray.texture.parent_path().filename(), "aff");
  EXPECT_EQ(gray.diffuse, glm::dvec3(0.6, 0.5, 0.4));
  EXPECT_EQ(gray.ambient, glm::dvec3(0.1));
  bool found_checker = false;
  for (const Material& m : s.materials) {
    if (m.texture.filename() == "checker.ppm") {
      found_checker = true;
      EXPECT_EQ(m.texture.parent_path().filename(), "TextureFiles");
    }
  }
  EXPECT_TRUE(found_checker);
}

TEST_F(HandSceneTest, BuildsTheTransformTree) {
  const Scene& s = *scene_;
  ASSERT_EQ(s.nodes.size(), 4u);
  EXPECT_EQ(s.nodes[0].children, (std::vector<int>{1, 2, 3}));
  const Node& xs = s.nodes[1];
  EXPECT_EQ(xs.kind, Node::Kind::kStatic);
  EXPECT_EQ(xs.scale, glm::dvec3(2.0));
  EXPECT_EQ(xs.axis, glm::dvec3(0, 1, 0));
  EXPECT_EQ(xs.angle_deg, 90.0);
  EXPECT_EQ(xs.translation, glm::dvec3(1, 0, 0));
  EXPECT_EQ(xs.meshes.size(), 2u);  // its own m and part.aff's (not_there.aff is skipped)
  EXPECT_EQ(s.nodes[2].kind, Node::Kind::kAnimated);
  EXPECT_EQ(s.nodes[3].name, "blinker");
  EXPECT_EQ(s.nodes[0].animated_triangles.size(), 1u);
  EXPECT_EQ(s.nodes[0].animated_triangles[0].times, (std::vector<double>{0.0, 2.0}));
}

// Corner k of an m triangle is (v_k, n_k, t_k); de-indexing keeps exactly that.
TEST_F(HandSceneTest, DeindexesMeshCornersIntoUniqueTuples) {
  const TriangleSet& m = scene_->nodes[1].meshes[0];
  const glm::vec3 v[] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  const glm::vec3 n[] = {{0, 0, 1}, {0, 0, -1}};
  const glm::vec2 t[] = {{0, 0}, {1, 0}, {1, 1}};
  const int rows[2][9] = {{0, 1, 2, 0, 0, 0, 0, 1, 2}, {0, 2, 3, 1, 1, 1, 0, 2, 1}};
  ASSERT_EQ(m.triangle_count(), 2u);
  EXPECT_EQ(m.positions.size(), 6u);  // 6 distinct (v, n, t) corners
  for (int tri = 0; tri < 2; ++tri) {
    for (int k = 0; k < 3; ++k) {
      const uint32_t i = m.indices[size_t(3 * tri + k)];
      EXPECT_EQ(m.positions[i], v[rows[tri][k]]);
      EXPECT_EQ(m.normals[i], n[rows[tri][3 + k]]);
      EXPECT_EQ(m.uvs[i], t[rows[tri][6 + k]]);
    }
  }
}

TEST_F(HandSceneTest, ReadsKeyframeBlocks) {
  const Keyframes& k = scene_->keyframes.at("spinner");
  EXPECT_EQ(k.translation.size(), 4u);
  EXPECT_EQ(k.scale.size(), 4u);
  ASSERT_EQ(k.rotation.size(), 4u);
  EXPECT_DOUBLE_EQ(k.rotation[2].angle, std::numbers::pi);  // degrees on file, radians here
  ASSERT_EQ(k.visibility.size(), 2u);
  EXPECT_FALSE(k.visibility[0].visible);
  EXPECT_TRUE(k.visibility[1].visible);
  EXPECT_EQ(scene_->keyframes.count("camera"), 1u);
  EXPECT_EQ(scene_->keyframes.count("lamp"), 1u);
}

// ---- Malformed input: afr::Error with "file:line: " first ----------------------------------

struct Malformed {
  const char* what;
  const char* text;
  int line;
  const char* message;  // a part of the message
};

class MalformedTest : public ::testing::TestWithParam<Malformed> {};

TEST_P(MalformedTest, ThrowsWithFileAndLine) {
  const Malformed& m = GetParam();
  const auto dir = test::fresh_temp_dir("aff-bad");
  try {
    parse_aff_text(m.text, "bad.aff", dir);
    ADD_FAILURE() << m.what << ": no error";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind("bad.aff:" + std::to_string(m.line) + ": ", 0), 0u)
        << m.what << ": " << message;
    EXPECT_NE(message.find(m.message), std::string::npos) << m.what << ": " << message;
  }
  std::filesystem::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(
    AffParser, MalformedTest,
    ::testing::Values(
        Malformed{"unknown directive", "b 0 0 0\nq 1 2 3\n", 2, "unknown directive 'q'"},
        Malformed{"unknown long directive", "\n\nfmx 1\n", 3, "unknown directive 'fmx'"},
        Malformed{"number where a directive starts", "s 0 0 0 1 2\n", 1, "unknown directive"},
        Malformed{"truncated numbers", "fm 0.1 0.2 0.3\n0.4\nm\n", 3, "found 'm'"},
        Malformed{"end of file in a directive", "\ns 0 0 0", 2, "unexpected end of file"},
        Malformed{"malformed number", "b 0 0.5.1 0\n", 1, "found '0.5.1'"},
        Malformed{"integer count with a fraction", "p 3.0\n", 1, "found '3.0'"},
        Malformed{"stray open brace", "b 0 0 0\n{\n", 2, "'{'"},
        Malformed{"stray close brace", "# c\n}\n", 2, "'}' without a matching '{'"},
        Malformed{"unclosed transform", "\nxs 1 1 1 0 1 0 0 0 0 0\n{\np 3 0 0 0 1 0 0 0 1 0\n", 2,
                  "never closed"},
        Malformed{"xs without brace", "xs 1 1 1 0 1 0 0 0 0 0\np 3\n", 2, "expected '{'"},
        Malformed{"comment between xs and brace", "xs 1 1 1 0 1 0 0 0 0 0 # c\n{\n}\n", 1,
                  "expected '{'"},
        Malformed{"missing include", "\n\ni 0 nothere.aff\n", 3, "nothere.aff"},
        Malformed{"include above D once d raises it", "d 1\ni 1 missing.aff\n", 2, "missing.aff"},
        Malformed{"mesh index out of range",
                  "f 1 1 1 1 0 0 0 0\nm vertices 3 0 0 0 1 0 0 0 1 0\ntriangles 1\n0 1 3\n", 4,
                  "vertex index 3 out of range"},
        Malformed{"mesh without triangles keyword", "m vertices 1 0 0 0\nfaces 0\n", 2,
                  "expected 'normals', 'texturecoords' or 'triangles'"},
        Malformed{"unknown keyframe type", "k a {\n  wobble 4\n}\n", 2,
                  "unknown keyframe type 'wobble'"},
        Malformed{"too few rotation keys", "k a {\n rot 2\n 0 0 1 0 0 0 0 0\n}\n", 2,
                  "at least 4 keys"},
        Malformed{"too few distinct key times once sorted",
                  "k a {\n transl 4\n 1 0 0 0 0 0 0\n 0 0 0 0 0 0 0\n 1 0 0 0 0 0 0\n"
                  " 0 0 0 0 0 0 0 }\n",
                  2, "2 keys at distinct times once sorted; it needs 4"},
        Malformed{"view keyword out of order", "v\nfrom 0 0 0\nup 0 1 0\n", 3, "expected 'at'"},
        Malformed{"missing texture", "m vertices 1 0 0 0\ntexturecoords 1 nope.ppm\n", 2,
                  "texture 'nope.ppm' not found"},
        // Bad input the fuzz target reports as out-of-memory, a hang or undefined behaviour
        // unless the parser refuses it (docs/robustness.md, "Fuzzing").
        Malformed{"polygon count beyond the file", "p 3 0 0 0 1 0 0 0 1 0\np 2000000000\n", 2,
                  "a vertex count 2000000000 is more than the rest of the file holds"},
        Malformed{"mesh count beyond the file", "m vertices 2 0 0 0 1 1 1 triangles 3\n0 1 1", 1,
                  "a triangle count 3 is more than the rest of the file holds"},
        Malformed{"tpa count beyond the file", "tpa 100000000\n", 1, "more than the rest"},
        Malformed{"key count beyond the file", "k a {\n visibility 1000000000\n", 2,
                  "a key count 1000000000 is more than the rest of the file holds"},
        Malformed{"too many frames", "\na 0 1 200000000\n", 2, "200000000 frames"},
        Malformed{"negative frames", "a 0 1 -3\n", 1, "-3 frames"},
        Malformed{"nan radius", "s 0 0 0 nan\n", 1, "found 'nan', which is not a finite number"},
        Malformed{
            "infinite key time",
            "k a { transl 4\n 0 0 0 0 0 0 0\n inf 0 0 0 0 0 0\n 2 0 0 0 0 0 0\n 3 0 0 0 0 0 0 }\n",
            3, "not a finite number"}));

TEST(AffParserTest, TransformsNestedTooDeepAreRefused) {
  std::string text;
  for (int i = 0; i < 1001; ++i) text += "xs 1 1 1 0 1 0 0 0 0 0 {\n";
  const auto dir = test::fresh_temp_dir("aff-deep");
  try {
    parse_aff_text(text, "deep.aff", dir);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "deep.aff:1001: transforms nested more than 1000 deep");
  }
  std::filesystem::remove_all(dir);
}

// A long parse says how far it is: with lines as often as they may come, a file of 10,000
// polygons gets progress lines naming it, the bytes read of its size and the triangles so far,
// rising; with the default interval (2 s) a small file gets none.
TEST(AffParserTest, ALongParseLogsItsProgress) {
  std::string text = "f 1 1 1 1 0 0 0 0\n";
  for (int i = 0; i < 10000; ++i) {
    const std::string x = std::to_string(i);
    text += "p 3\n" + x + " 0 0\n" + x + " 1 0\n" + x + " 0 1\n";
  }
  const auto dir = test::fresh_temp_dir("aff-progress");
  {
    testing::LogCapture log;
    ParseOptions often;
    often.progress_interval = 0.0;
    parse_aff_text(text, "big.aff", dir, often);
    const std::vector<std::string> lines = log.lines_with("parsing big.aff: ");
    ASSERT_GE(lines.size(), 2u);  // one per 4096 directives
    EXPECT_NE(lines.back().find(fmt::format("of {:.1f} MB", double(text.size()) / 1e6)),
              std::string::npos)
        << lines.back();
    // The material, then 8191 polygons, at the last line (after 2 x 4096 directives).
    EXPECT_NE(lines.back().find("8191 triangles so far"), std::string::npos) << lines.back();
  }
  {
    testing::LogCapture log;
    parse_aff_text(text, "big.aff", dir);
    EXPECT_TRUE(log.lines_with("parsing big.aff").empty());
  }
  std::filesystem::remove_all(dir);
}

TEST(AffParserTest, ErrorsInsideAnIncludeNameThatFileAndLine) {
  const auto dir = test::fresh_temp_dir("aff-bad-include");
  test::write_file(dir / "inner.aff", "# fine\nb 0 0 0\nz\n");
  try {
    parse_aff_text("i 0 inner.aff\n", "outer.aff", dir);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("inner.aff:3: unknown directive 'z'"), std::string::npos) << message;
  }
  std::filesystem::remove_all(dir);
}

// An include emptied by a failed copy (one of the museum's files in a public copy of BART)
// adds nothing: the conversion goes on and says so once, however often it is included.
TEST(AffParserTest, AnEmptyIncludeIsNamedInAWarning) {
  const auto dir = test::fresh_temp_dir("aff-empty-include");
  test::write_file(dir / "empty.aff", "");
  test::write_file(dir / "comments.aff", "% only a comment\n# and another\n\n");
  test::write_file(dir / "tri.aff", "p 3 0 0 0 1 0 0 0 1 0\n");
  const Scene s = parse_aff_text(
      "f 1 1 1 1 0 0 0 0\ni 0 empty.aff\ni 0 tri.aff\ni 0 empty.aff\ni 0 comments.aff\n",
      "main.aff", dir);
  EXPECT_EQ(s.nodes[0].meshes.size(), 1u);
  EXPECT_EQ(s.warnings,
            (std::vector<std::string>{
                "main.aff:2: include file 'empty.aff' holds no directives: it adds nothing to "
                "the scene",
                "main.aff:5: include file 'comments.aff' holds no directives: it adds nothing "
                "to the scene"}));
  std::filesystem::remove_all(dir);
}

TEST(AffParserTest, BracesMayOpenInOneFileAndCloseInAnother) {
  const auto dir = test::fresh_temp_dir("aff-braces");
  test::write_file(dir / "open.aff", "xs 1 1 1 0 1 0 0 0 0 0 {\n");
  test::write_file(dir / "close.aff", "}\n");
  const Scene s = parse_aff_text(
      "i 0 open.aff\np 3 0 0 0 1 0 0 0 1 0\ni 0 close.aff\n"
      "p 3 0 0 0 1 0 0 0 1 0\n",
      "main.aff", dir);
  ASSERT_EQ(s.nodes.size(), 2u);
  EXPECT_EQ(s.nodes[1].meshes.size(), 1u);
  EXPECT_EQ(s.nodes[0].meshes.size(), 1u);
  std::filesystem::remove_all(dir);
}

TEST(AffParserTest, TheLastDefinitionOfAKeyframeNameWins) {
  const auto dir = test::fresh_temp_dir("aff-k");
  const Scene s = parse_aff_text("k a { visibility 1 0 0 }\nk a { visibility 1 0 1 }\nx a { }\n",
                                 "main.aff", dir);
  ASSERT_EQ(s.keyframes.at("a").visibility.size(), 1u);
  EXPECT_TRUE(s.keyframes.at("a").visibility[0].visible);
  std::filesystem::remove_all(dir);
}

// BART's robots (Robot1.aff, k gun_rot1) hold a channel whose second run of keys starts
// before the first one ends: it is sorted, the later key in the file kept at a shared time.
TEST(AffParserTest, KeyTimesThatGoBackwardsAreSortedWithAWarning) {
  const auto dir = test::fresh_temp_dir("aff-backwards");
  const Scene s = parse_aff_text(
      "x a { }\n"
      "k a {\n"
      " transl 7\n"
      " 0 0 0 0 0 0 0\n"
      " 1 1 0 0 0 0 0\n"
      " 2 2 0 0 0 0 0\n"
      " 3 3 0 0 0 0 0\n"
      " 1.5 9 0 0 0 0 0\n"
      " 2 7 0 0 0 0 0\n"
      " 4 4 0 0 0 0 0\n"
      " rot 4\n"
      " 0 0 1 0 0 0 0 0\n"
      " 0 0 1 0 0 0 0 0\n"
      " 1 0 1 0 90 0 0 0\n"
      " 1 0 1 0 90 0 0 0\n"
      "}\n",
      "main.aff", dir);
  const Keyframes& k = s.keyframes.at("a");
  std::vector<double> times, xs;
  for (const TcbKey& key : k.translation) {
    times.push_back(key.t);
    xs.push_back(key.value.x);
  }
  EXPECT_EQ(times, (std::vector<double>{0, 1, 1.5, 2, 3, 4}));
  EXPECT_EQ(xs, (std::vector<double>{0, 1, 9, 7, 3, 4}));
  // An ordered channel keeps its repeated times (they shape KB tangents).
  EXPECT_EQ(k.rotation.size(), 4u);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_EQ(s.warnings[0],
            "main.aff:3: k a: transl key times go backwards (3 then 1.5 at main.aff:8); keys "
            "sorted by time, 1 of 7 dropped where a later key in the file has the same time");
  std::filesystem::remove_all(dir);
}

TEST(AffParserTest, ParsesTheKitchenQuickly) {
  const auto path = test::kitchen_aff();
  if (path.empty()) GTEST_SKIP() << "BART kitchen not found (AFR_SHARED_DIR)";
  const auto start = std::chrono::steady_clock::now();
  const Scene s = parse_aff_file(path);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  // aff-format.md section 2: 110 561 triangles in the expanded scene, 416 xs + 7 x.
  EXPECT_EQ(s.triangle_count(), 110561u);
  EXPECT_EQ(s.nodes.size(), 1u + 416u + 7u);
  EXPECT_EQ(s.lights.size(), 6u);
  EXPECT_TRUE(s.warnings.empty());
  // A guard against a parser gone quadratic, not a speed figure (well under a second in
  // Release; bench/ measures the converter).
  EXPECT_LT(seconds, afr::testing::scaled(5.0));
  RecordProperty("parse_seconds", std::to_string(seconds));
}

}  // namespace
}  // namespace afr::aff
