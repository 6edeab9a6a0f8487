// dump/verify JSON must parse whatever bytes a blob's strings hold.
#include "kiln/tools/json_writer.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <sstream>

namespace kiln {
namespace {

TEST(JsonWriter, OutputParsesAndKeepsValues) {
  std::ostringstream out;
  JsonWriter j(out);
  const std::string odd =
      std::string("quote\" back\\ nl\n ctl\x01 ") + "caf\xC3\xA9 bad\xFF\xC0 end";
  j.begin_object().field("name", odd).field("count", std::uint64_t{18446744073709551615ull});
  j.key("list").begin_array().value(1.5).null().value(true).end_array();
  j.key("empty").begin_object().end_object();
  j.end_object();
  const auto parsed = nlohmann::json::parse(out.str());
  EXPECT_EQ(parsed["count"].get<std::uint64_t>(), 18446744073709551615ull);
  EXPECT_EQ(parsed["list"][0], 1.5);
  EXPECT_TRUE(parsed["list"][1].is_null());
  EXPECT_EQ(parsed["list"][2], true);
  EXPECT_TRUE(parsed["empty"].empty());
  // Valid UTF-8 and escapes survive; invalid bytes become U+FFFD.
  EXPECT_EQ(parsed["name"].get<std::string>(),
            std::string("quote\" back\\ nl\n ctl\x01 caf\xC3\xA9 bad\xEF\xBF\xBD\xEF\xBF\xBD end"));
}

}  // namespace
}  // namespace kiln
