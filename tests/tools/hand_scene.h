// A small hand-written AFF scene that uses every directive of the format (with CRLF line ends,
// a Latin-1 comment, an include that sets the includer's material, a skipped include, a P3
// texture with comments and maxval 15 and a P6 one with a trailing byte), written to a
// directory laid out like BART's: <dir>/aff/*.aff and <dir>/TextureFiles/*.ppm.
#pragma once

#include <filesystem>
#include <fstream>
#include <string>

namespace afr::test {

// Triangles of the expanded scene, counted by hand: p 5 (3) + pp 4 (2) + sphere (960 at 32 x 16)
// + cone (64 at 32 slices) + tt (1) + ttp (1) + tpa (1) + the xs mesh (2) + part.aff (1)
// + spinner (1) + blinker (1).
constexpr size_t kHandSceneTriangles = 3 + 2 + 960 + 64 + 1 + 1 + 1 + 2 + 1 + 1 + 1;

inline const char* hand_scene_text() {
  return R"(# every directive of the format; Latin-1 here: caf)"
         "\xe9"
         R"(
% a percent comment
d 0
v
from 0 1 5
at 0 1 0
up 0 1 0
angle 45
hither 0.00001
resolution 320 240
b 0.1 0.2 0.3
am 0.5 0.5 0.5
l 1 2 3
l 4 5 6 0.5 0.25 1
la lamp 0 3 0 1 1 1
a 0 2 21 % frames
f 1 0.5 0.25 0.8 0.3 20 0 1
p 5
 0 0 0  1 0 0  2 1 0  1 2 0  0 1 0
pp 4
 0 0 1 0 0 1
 1 0 1 0 0 1
 1 1 1 0 0 1
 0 1 1 0 0 1
s 0 0 0 1
c 0 0 0 1  0 1 0 0.5
fm 0.1 0.1 0.1  0.6 0.5 0.4  0.2 0.2 0.2  8 0 0
tt checker.ppm
 0 0 0 0 0
 1 0 0 1 0
 0 1 0 0 1
ttp checker.ppm
 0 0 0 0 0 1 0 0
 1 0 0 0 0 1 1 0
 0 1 0 0 0 1 0 1
tpa 2
 0.0
 0 0 0 0 0 1
 1 0 0 0 0 1
 0 1 0 0 0 1
 2.0
 0 0 1 0 0 1
 1 0 1 0 0 1
 0 1 1 0 0 1
xs 2 2 2  0 1 0 90  1 0 0
{
  m
   vertices 4
    0 0 0  1 0 0  1 1 0  0 1 0
   normals 2
    0 0 1  0 0 -1
   texturecoords 3 gray.ppm
    0 0  1 0  1 1
   triangles 2
    0 1 2  0 0 0  0 1 2
    0 2 3  1 1 1  0 2 1
  i 0 part.aff
  i 1 not_there.aff
}
x spinner
{
  m
   vertices 3
    0 0 0  1 0 0  0 1 0
   triangles 1
    0 1 2
}
k spinner
{
  transl 4
   0   0 0 0  0 0 0
   0.5 1 0 0  0 0 0
   1.5 2 0 0  0 0 0
   2   3 0 0  0 0 0
  rot 4
   0   0 1 0 0    0 0 0
   0.5 0 1 0 90   0 0 0
   1.5 0 1 0 180  0 0 0
   2   0 1 0 270  0 0 0
  scale 4
   0   1 1 1  0 0 0
   0.5 1 1 1  0 0 0
   1.5 2 2 2  0 0 0
   2   3 3 3  0 0 0
  visibility 2
   0.5 0
   1.5 1
}
k lamp {
  transl 4
  -1 0 3 0  0 0 0
   0 0 3 0  0 0 0
   2 2 3 0  0 0 0
   3 2 3 0  0 0 0
}
x blinker
{
  p 3 0 0 0 1 0 0 0 1 0
}
k blinker
{
  visibility 1
   1.0 0
}
k camera
{
  transl 4
  -1 0 1 5  0 0 0
   0 0 1 5  0 0 0
   2 0 1 3  0 0 0
   3 0 1 3  0 0 0
  rot 4
  -1 0 1 0 0   0 0 0
   0 0 1 0 0   0 0 0
   2 0 1 0 30  0 0 0
   3 0 1 0 30  0 0 0
}
)";
}

// The included file: its `fm` stays the current material after it ends.
inline const char* hand_part_text() {
  return "fm 0.3 0.3 0.3  0.9 0.9 0.9  0 0 0  0 0 0\n"
         "m\n vertices 3\n  0 0 0 1 0 0 0 1 0\n triangles 1\n  0 1 2\n";
}

inline void write_file(const std::filesystem::path& path, const std::string& bytes) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out << bytes;
}

// Writes the scene under `dir`; returns the root .aff.
inline std::filesystem::path write_hand_scene(const std::filesystem::path& dir) {
  std::string text = hand_scene_text();
  std::string crlf;
  for (const char c : text) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  write_file(dir / "aff" / "scene.aff", crlf);
  write_file(dir / "aff" / "part.aff", hand_part_text());
  // ASCII P3 with comments and maxval 15: red, green / blue, gray 7 (8-bit: 7 * 17 = 119).
  write_file(dir / "TextureFiles" / "checker.ppm",
             "P3\n# a comment\n2 2\n# another\n15\n15 0 0   0 15 0\n0 0 15   7 7 7\n");
  // Binary P6 found next to the .aff (the fallback), with one extra trailing byte.
  write_file(dir / "aff" / "gray.ppm", std::string("P6\n# c\n2 1\n255\n") +
                                           std::string("\x0a\x14\x1e\x28\x32\x3c", 6) + "\n");
  return dir / "aff" / "scene.aff";
}

}  // namespace afr::test
