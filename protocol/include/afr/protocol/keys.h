// CurveZMQ keys: generation, the key files of afr, and allow-lists of sampler public keys.
// Keys are Z85 text (40 characters for 32 bytes), as libzmq takes them.
//
// Key pair file (secret; written with mode 0600):   Public key file:
//   # afr CurveZMQ key pair ...                      # afr CurveZMQ public key ...
//   public-key = <40 chars>                          public-key = <40 chars>
//   secret-key = <40 chars>
// Allow-list file: one public key per line, either bare or as "public-key = <key>", optionally
// followed by whitespace and a name; '#' starts a comment. A key pair file or a public key
// file is also a valid one-key allow-list.
#pragma once

#include <string>
#include <vector>

namespace afr::protocol {

struct CurveKeyPair {
  std::string public_key;  // Z85
  std::string secret_key;  // Z85
};

// True when libzmq was built with CURVE (Debian's is).
bool curve_available();

// A fresh pair from libzmq (zmq_curve_keypair). Throws afr::Error without CURVE support.
CurveKeyPair generate_curve_keypair();

// 40 Z85 characters that decode to 32 bytes.
bool is_curve_key(const std::string& z85);

// The public key that belongs to a secret key. Throws afr::Error for a malformed key.
std::string curve_public_key(const std::string& secret_key);

// Write the two files (the secret one with mode 0600). Throw afr::Error naming the file.
void save_curve_keypair(const std::string& path, const CurveKeyPair& pair);
void save_curve_public_key(const std::string& path, const std::string& public_key);

// Read key files; throw afr::Error naming the file and line for anything malformed, and for a
// pair whose public key does not belong to its secret key.
CurveKeyPair load_curve_keypair(const std::string& path);
std::string load_curve_public_key(const std::string& path);
std::vector<std::string> load_allowed_keys(const std::string& path);

// The keys of a display and its samplers, for `display_node keygen DIR --samplers N`: DIR/
// display.key and display.pub, sampler-i.key and .pub for i = 1..N, and samplers.allow with
// the samplers' public keys and the display's own (the followers of a wall use the display's
// key pair). Throws afr::Error naming a file it cannot write.
void write_key_folder(const std::string& dir, int samplers);

}  // namespace afr::protocol
