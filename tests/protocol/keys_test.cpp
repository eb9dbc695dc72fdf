#include <afr/protocol/keys.h>

#include <afr/common/error.h>
#include <afr/protocol/scene_hash.h>

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <zmq.h>

#include <array>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace afr::protocol {
namespace {

namespace fs = std::filesystem;

class KeysTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/afr-keys-XXXXXX";
    ASSERT_NE(mkdtemp(tmpl), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const char* name) const { return (dir_ / name).string(); }
  void write(const char* name, const std::string& text) const { std::ofstream(path(name)) << text; }

  fs::path dir_;
};

// A key pair whose keys contain the characters that look like syntax ('#' and '='): Z85 uses
// both, and a parser that treats them as comments or separators breaks on such keys.
CurveKeyPair awkward_pair() {
  for (;;) {
    CurveKeyPair p = generate_curve_keypair();
    if (p.public_key[0] == '#' || (p.public_key.find('#') != std::string::npos &&
                                   p.public_key.find('=') != std::string::npos)) {
      return p;
    }
  }
}

TEST_F(KeysTest, GeneratedPairsAreValidAndConsistent) {
  ASSERT_TRUE(curve_available());
  const CurveKeyPair a = generate_curve_keypair(), b = generate_curve_keypair();
  EXPECT_TRUE(is_curve_key(a.public_key));
  EXPECT_TRUE(is_curve_key(a.secret_key));
  EXPECT_NE(a.public_key, b.public_key);
  EXPECT_EQ(curve_public_key(a.secret_key), a.public_key);
  // Independently: the Z85 text decodes to 32 bytes.
  std::array<uint8_t, 32> raw{};
  EXPECT_NE(zmq_z85_decode(raw.data(), a.public_key.c_str()), nullptr);
  EXPECT_FALSE(is_curve_key(a.public_key.substr(1)));
  EXPECT_FALSE(is_curve_key(a.public_key.substr(1) + " "));  // space is not Z85
}

TEST_F(KeysTest, PairFilesRoundTripAndTheSecretOneIsPrivate) {
  const CurveKeyPair pair = awkward_pair();
  save_curve_keypair(path("display.key"), pair);
  save_curve_public_key(path("display.pub"), pair.public_key);
  const CurveKeyPair loaded = load_curve_keypair(path("display.key"));
  EXPECT_EQ(loaded.public_key, pair.public_key);
  EXPECT_EQ(loaded.secret_key, pair.secret_key);
  EXPECT_EQ(load_curve_public_key(path("display.pub")), pair.public_key);
  EXPECT_EQ(load_curve_public_key(path("display.key")), pair.public_key);
  struct stat st;
  ASSERT_EQ(stat(path("display.key").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  // A public key file is not a key pair.
  EXPECT_THROW(load_curve_keypair(path("display.pub")), Error);
}

TEST_F(KeysTest, AllowListsAcceptTheDocumentedForms) {
  const CurveKeyPair a = awkward_pair(), b = generate_curve_keypair(), c = generate_curve_keypair(),
                     d = generate_curve_keypair();
  write("allowed", "# samplers of the lab\n\n" + a.public_key + "\n   " + b.public_key +
                       "   sampler-2 # the fast one\npublic-key = \"" + c.public_key +
                       "\"\npublic-key=" + d.public_key + "\n");
  const std::vector<std::string> keys = load_allowed_keys(path("allowed"));
  EXPECT_EQ(keys,
            (std::vector<std::string>{a.public_key, b.public_key, c.public_key, d.public_key}));
  save_curve_keypair(path("one.key"), a);
  EXPECT_EQ(load_allowed_keys(path("one.key")), std::vector<std::string>{a.public_key});
  write("empty", "# nobody yet\n");
  EXPECT_TRUE(load_allowed_keys(path("empty")).empty());
}

TEST_F(KeysTest, MalformedFilesAreRefusedWithFileAndLine) {
  const CurveKeyPair a = generate_curve_keypair(), b = generate_curve_keypair();
  const auto message = [](auto&& f) {
    try {
      f();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  write("short", a.public_key + "\n" + a.public_key.substr(0, 39) + "\n");
  EXPECT_NE(message([&] { load_allowed_keys(path("short")); }).find("short:2"), std::string::npos);
  write("mixed", "public-key = " + a.public_key + "\nsecret-key = " + b.secret_key + "\n");
  EXPECT_NE(message([&] { load_curve_keypair(path("mixed")); }).find("does not belong"),
            std::string::npos);
  write("field", "private = " + a.secret_key + "\n");
  EXPECT_NE(message([&] { load_curve_keypair(path("field")); }).find("field:1"), std::string::npos);
  EXPECT_NE(message([&] { load_allowed_keys(path("missing")); }).find("cannot open"),
            std::string::npos);
  write("two", a.public_key + "\n" + b.public_key + "\n");
  EXPECT_NE(message([&] { load_curve_public_key(path("two")); }).find("more than one"),
            std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// Scene hashes: BLAKE2b-256, checked against the published test values (RFC 7693 gives
// BLAKE2b-512; these are the 256-bit outputs listed by the BLAKE2 reference implementation).

TEST(SceneHashTest, MatchesKnownBlake2b256Values) {
  EXPECT_EQ(to_hex(scene_hash({})),
            "0e5751c026e543b2e8ab2eb06099daa1d1e5df47778f7787faab45cdf12fe3a8");
  const std::string abc = "abc";
  EXPECT_EQ(to_hex(scene_hash({reinterpret_cast<const uint8_t*>(abc.data()), abc.size()})),
            "bddd813c634239723171ef3fee98579b94964e3bb1cb3e427262c8c068d52319");
}

TEST(SceneHashTest, IncrementalEqualsOneShot) {
  std::vector<uint8_t> data(100000);
  for (size_t i = 0; i < data.size(); ++i) data[i] = uint8_t(i * 7 + (i >> 8));
  SceneHasher h;
  size_t at = 0;
  for (size_t step : {1, 63, 64, 65, 1000, 4096}) {
    h.update({data.data() + at, step});
    at += step;
  }
  h.update({data.data() + at, data.size() - at});
  const SceneHash whole = h.finish();
  EXPECT_EQ(whole, scene_hash(data));
  data[5000] ^= 1;
  EXPECT_NE(scene_hash(data), whole);
}

}  // namespace
}  // namespace afr::protocol
