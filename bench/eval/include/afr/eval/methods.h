// The rendering methods that the evaluation compares (paper section 7, Table 1 and Figure 8,
// plus framed rendering with temporal accumulation), by name.
#pragma once

#include <span>
#include <string_view>

namespace afr::eval {

enum class Method {
  kFramed60,                // R/60 samples per frame at reduced resolution, upsampled, 60 Hz
  kFramedFullRes,           // full-resolution frames as fast as R allows
  kFrameless,               // traditional frameless: uniform random samples, newest per pixel
  kAdaptive,                // afr: adaptive sampler (r = 5) and adaptive reconstruction
  kAdaptiveNoReprojection,  // the adaptive sampler with r = 0, reconstruction without reprojection
  kFullRes60,               // full resolution at 60 Hz (W x H x 60 samples/s), no antialiasing
  kFramedTaa,               // framed 60 Hz with jitter and temporal accumulation (TAA)
};

// Every method, in the order of the tables.
std::span<const Method> all_methods();

// Short names for flags and files ("framed-60hz", "framed-full-res", "frameless", "adaptive",
// "adaptive-no-reproj", "full-res-60hz", "framed-taa") and labels for tables and plots.
const char* method_name(Method method);
const char* method_label(Method method);
// Throws afr::Error naming the text and the accepted names.
Method parse_method(std::string_view name);

// False for the full-res 60 Hz reference, whose rate is W x H x 60 whatever R is.
bool method_uses_rate(Method method);
// True for the methods that run the sampler and reconstructor libraries.
bool method_is_frameless(Method method);
// False for the methods whose images no seed changes (framed 60 Hz and full res 60 Hz trace
// pixel centers at refresh-locked times): one run of them stands for every seed.
bool method_uses_seed(Method method);

}  // namespace afr::eval
