// Parser of BART AFF scene files (shared/reference/aff-format.md): reads the root file and
// every file it includes as bytes, and returns the expanded scene. Every malformed input
// (unknown directive, missing or malformed number, unbalanced or stray brace, missing include
// or texture, ...) throws afr::Error whose message starts with "file:line: ".
#pragma once

#include "aff_scene.h"
#include "tessellate.h"

#include <filesystem>
#include <string>
#include <string_view>

namespace afr::aff {

struct ParseOptions {
  TessellationOptions tessellation;
  int detail_level = 0;  // D before any `d`: includes with a level above it are skipped
  // A long parse says how far it is: a log line (info) at most this often, naming the file, how
  // much of it is read, and the triangles so far. <= 0: a line per file read.
  double progress_interval = 2.0;
};

// Parses `path` and its includes. Includes and textures are resolved as the format says:
// include names against the root file's directory (then the including file's), texture names
// as <root dir>/../TextureFiles/NAME, then <root dir>/NAME.
Scene parse_aff_file(const std::filesystem::path& path, const ParseOptions& options = {});

// Parses AFF text held in memory as if it were the file `name` in directory `root_dir`.
Scene parse_aff_text(std::string_view text, const std::string& name,
                     const std::filesystem::path& root_dir, const ParseOptions& options = {});

}  // namespace afr::aff
