#include <afr/display/backend.h>
#include <gtest/gtest.h>
namespace afr { namespace { TEST(BackendTest, Parse) { EXPECT_EQ(parse_backend("gl"), Backend::kGl); } } }
