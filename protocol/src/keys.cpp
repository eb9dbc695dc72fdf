#include <afr/protocol/keys.h>

#include <cstdio>
#include <filesystem>

#include <afr/common/error.h>

#include <zmq.h>

#include <sys/stat.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

namespace afr::protocol {

namespace {

constexpr const char* kPublicField = "public-key";
constexpr const char* kSecretField = "secret-key";

struct KeyLine {
  std::string field;  // "public-key", "secret-key", or empty for a bare key
  std::string key;
};

// Splits "field = key [name]" or "key [name]"; comments and blank lines give nothing. Z85
// uses '#' and '=' but never whitespace, so the key is a whitespace-delimited token: a line is
// a comment only when it starts with '#' and its first token is not a key.
bool parse_line(const std::string& raw, KeyLine* out) {
  std::istringstream tokens(raw);
  std::string first;
  if (!(tokens >> first)) return false;
  out->field.clear();
  for (const char* field : {kPublicField, kSecretField}) {
    const size_t n = std::strlen(field);
    if (first.compare(0, n, field) != 0) continue;
    // "field = key", "field= key", "field =key" or "field=key".
    std::string rest = first.substr(n);
    if (rest.empty() && !(tokens >> rest)) rest.clear();
    if (rest.empty() || rest[0] != '=') break;  // not this form: treat as a bare key
    rest.erase(0, 1);
    if (rest.empty()) tokens >> rest;
    out->field = field;
    first = rest;
    break;
  }
  if (out->field.empty() && first[0] == '#' && !is_curve_key(first)) return false;
  // Quotes (as in czmq's certificates) are allowed around the key.
  if (first.size() >= 2 && first.front() == '"' && first.back() == '"') {
    first = first.substr(1, first.size() - 2);
  }
  out->key = first;
  return true;
}

std::vector<std::string> read_lines(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(path + ": cannot open (" + std::strerror(errno) + ")");
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

void write_file(const std::string& path, const std::string& text, mode_t mode) {
  std::ofstream out(path, std::ios::trunc);
  if (!out) throw Error(path + ": cannot write (" + std::strerror(errno) + ")");
  out << text;
  out.close();
  if (!out) throw Error(path + ": write failed");
  if (::chmod(path.c_str(), mode) != 0) {
    throw Error(path + ": cannot set permissions (" + std::strerror(errno) + ")");
  }
}

std::string where(const std::string& path, size_t line) {
  return path + ":" + std::to_string(line + 1);
}

}  // namespace

bool curve_available() { return zmq_has("curve") != 0; }

CurveKeyPair generate_curve_keypair() {
  char pub[41] = {}, sec[41] = {};
  if (zmq_curve_keypair(pub, sec) != 0) {
    throw Error(std::string("cannot generate a CurveZMQ key pair: ") + zmq_strerror(zmq_errno()));
  }
  return {pub, sec};
}

bool is_curve_key(const std::string& z85) {
  if (z85.size() != 40) return false;
  std::array<uint8_t, 32> bytes{};
  return zmq_z85_decode(bytes.data(), z85.c_str()) != nullptr;
}

std::string curve_public_key(const std::string& secret_key) {
  if (!is_curve_key(secret_key)) throw Error("malformed CurveZMQ secret key");
  char pub[41] = {};
  if (zmq_curve_public(pub, secret_key.c_str()) != 0) {
    throw Error(std::string("cannot derive a CurveZMQ public key: ") + zmq_strerror(zmq_errno()));
  }
  return pub;
}

void save_curve_keypair(const std::string& path, const CurveKeyPair& pair) {
  if (!is_curve_key(pair.public_key) || !is_curve_key(pair.secret_key)) {
    throw Error(path + ": refusing to save a malformed key pair");
  }
  write_file(path,
             "# afr CurveZMQ key pair. Keep this file secret; give out the .pub file.\n" +
                 std::string(kPublicField) + " = " + pair.public_key + "\n" + kSecretField + " = " +
                 pair.secret_key + "\n",
             0600);
}

void save_curve_public_key(const std::string& path, const std::string& public_key) {
  if (!is_curve_key(public_key)) throw Error(path + ": refusing to save a malformed public key");
  write_file(
      path,
      "# afr CurveZMQ public key. Add it to a display's allow-list to admit this sampler.\n" +
          std::string(kPublicField) + " = " + public_key + "\n",
      0644);
}

CurveKeyPair load_curve_keypair(const std::string& path) {
  const std::vector<std::string> lines = read_lines(path);
  CurveKeyPair pair;
  for (size_t i = 0; i < lines.size(); ++i) {
    KeyLine kl;
    if (!parse_line(lines[i], &kl)) continue;
    std::string* target = kl.field == kPublicField   ? &pair.public_key
                          : kl.field == kSecretField ? &pair.secret_key
                                                     : nullptr;
    if (!target) throw Error(where(path, i) + ": expected public-key = or secret-key =");
    if (!is_curve_key(kl.key)) throw Error(where(path, i) + ": malformed key (40 Z85 characters)");
    if (!target->empty()) throw Error(where(path, i) + ": " + kl.field + " given twice");
    *target = kl.key;
  }
  if (pair.secret_key.empty()) throw Error(path + ": no secret-key (is this a public key file?)");
  if (pair.public_key.empty()) throw Error(path + ": no public-key");
  if (curve_public_key(pair.secret_key) != pair.public_key) {
    throw Error(path + ": the public key does not belong to the secret key");
  }
  return pair;
}

std::string load_curve_public_key(const std::string& path) {
  const std::vector<std::string> lines = read_lines(path);
  std::string key;
  for (size_t i = 0; i < lines.size(); ++i) {
    KeyLine kl;
    if (!parse_line(lines[i], &kl) || kl.field == kSecretField) continue;
    if (kl.field != kPublicField && !kl.field.empty()) {
      throw Error(where(path, i) + ": expected public-key =");
    }
    if (!is_curve_key(kl.key)) throw Error(where(path, i) + ": malformed key (40 Z85 characters)");
    if (!key.empty()) throw Error(where(path, i) + ": more than one public key");
    key = kl.key;
  }
  if (key.empty()) throw Error(path + ": no public key");
  return key;
}

std::vector<std::string> load_allowed_keys(const std::string& path) {
  const std::vector<std::string> lines = read_lines(path);
  std::vector<std::string> keys;
  for (size_t i = 0; i < lines.size(); ++i) {
    KeyLine kl;
    if (!parse_line(lines[i], &kl) || kl.field == kSecretField) continue;
    if (kl.field != kPublicField && !kl.field.empty()) {
      throw Error(where(path, i) + ": expected a public key");
    }
    if (!is_curve_key(kl.key)) throw Error(where(path, i) + ": malformed key (40 Z85 characters)");
    keys.push_back(kl.key);
  }
  return keys;
}

void write_key_folder(const std::string& dir, int samplers) {
  namespace fs = std::filesystem;
  fs::create_directories(dir);
  const CurveKeyPair display = generate_curve_keypair();
  save_curve_keypair((fs::path(dir) / "display.key").string(), display);
  save_curve_public_key((fs::path(dir) / "display.pub").string(), display.public_key);
  std::string allow = "# afr: sampler public keys the display admits (one per line)\n";
  allow += display.public_key + " display (wall followers)\n";
  for (int i = 1; i <= samplers; ++i) {
    const CurveKeyPair s = generate_curve_keypair();
    const std::string name = "sampler-" + std::to_string(i);
    save_curve_keypair((fs::path(dir) / (name + ".key")).string(), s);
    save_curve_public_key((fs::path(dir) / (name + ".pub")).string(), s.public_key);
    allow += s.public_key + " " + name + "\n";
  }
  const fs::path allow_file = fs::path(dir) / "samplers.allow";
  FILE* f = std::fopen(allow_file.c_str(), "w");
  if (!f || std::fputs(allow.c_str(), f) < 0 || std::fclose(f) != 0) {
    throw Error(allow_file.string() + ": cannot write");
  }
}

}  // namespace afr::protocol
