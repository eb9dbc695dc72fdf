// The display's web dashboard (docs/service.md, "Dashboard"), looked at as a person would: a
// real display and sampler, the page loaded in headless Chromium (Debian's `chromium`). The
// page counts what it loaded in #loads (images, history polls, periods, the latest period).
// Skipped, with the reason, where Chromium is not installed or cannot start.
#include "service_fixture.h"

#include <afr/common/image.h>
#include <afr/display/service/dashboard.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <regex>
#include <string>

namespace afr::testing {
namespace {

constexpr const char* kChromium = "/usr/bin/chromium";

struct PageLoads {
  int images = -1, histories = -1, periods = -1;
  std::string last;  // the latest period the page charted (JSON)
};

class DashboardTest : public ServiceTest {
 protected:
  // Loads the page in headless Chromium with `extra` arguments; returns its output.
  std::string chromium(std::vector<std::string> extra, const std::string& log) {
    std::vector<std::string> argv = {kChromium,
                                     "--headless",
                                     "--no-sandbox",
                                     "--disable-gpu",
                                     "--no-first-run",
                                     "--user-data-dir=" + path("chromium-" + log),
                                     "--virtual-time-budget=4000"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    argv.push_back("http://127.0.0.1:" + std::to_string(metrics_port()) + "/");
    Process p(argv, path(log));
    p.wait(scaled(90.0));
    return p.log();
  }

  PageLoads loads(const std::string& dom) {
    PageLoads l;
    std::smatch m;
    const std::regex span(
        R"re(<span id="loads" data-images="(\d+)" data-history="(\d+)" data-periods="(\d+)" data-last="([^"]*)")re");
    if (std::regex_search(dom, m, span)) {
      l.images = std::stoi(m[1]);
      l.histories = std::stoi(m[2]);
      l.periods = std::stoi(m[3]);
      l.last = m[4];
    }
    return l;
  }
};

// The feed alone: images only while asked for, a history bounded however long the display
// runs, and read from a time on.
TEST(DashboardFeedTest, ImagesWhileAskedAndABoundedHistory) {
  service::DashboardFeed feed;
  EXPECT_FALSE(feed.wants_image());            // nobody asked
  EXPECT_TRUE(feed.image_png(false).empty());  // asks
  EXPECT_TRUE(feed.wants_image());
  Image image(8, 4);
  image.at(1, 1) = glm::vec3(1.0f, 0.0f, 0.0f);
  feed.publish(image, image);
  EXPECT_FALSE(feed.wants_image());  // one was just made
  const std::string png = feed.image_png(false);
  ASSERT_GT(png.size(), 8u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
  for (int i = 0; i < 1000; ++i) {
    service::DashboardPeriod p;
    p.time = i;
    p.refresh_hz = 30.0 + i;
    p.samplers.push_back({7, 1000.0 * i, 0.5});
    feed.add_period(p);
    feed.add_event(i, "event " + std::to_string(i));
  }
  const nlohmann::json all = nlohmann::json::parse(feed.history_json(-1e30));
  ASSERT_EQ(all["periods"].size(), service::DashboardFeed::kMaxPeriods);
  EXPECT_EQ(all["events"].size(), service::DashboardFeed::kMaxEvents);
  EXPECT_EQ(all["periods"].back()["t"].get<double>(), 999.0);
  EXPECT_EQ(all["periods"].back()["samplers"][0]["rate"].get<double>(), 999000.0);
  const nlohmann::json recent = nlohmann::json::parse(feed.history_json(997.0));
  EXPECT_EQ(recent["periods"].size(), 2u);
  EXPECT_EQ(recent["events"].size(), 2u);
}

// 64 clients that connect and send half a request, then nothing, must not hold up /metrics
// (cpp-httplib's default, 8 threads waiting 5 s each, took about 40 s).
TEST_F(DashboardTest, SlowClientsDoNotHoldUpMetrics) {
  auto d = display({}, "display.log");
  ASSERT_TRUE(wait_until([&] { return !get_stats(metrics_port()).is_null(); }, scaled(10.0)))
      << d->log();
  std::vector<int> slow;
  for (int i = 0; i < 64; ++i) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    ASSERT_GE(fd, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(uint16_t(metrics_port()));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)), 0);
    const char partial[] = "GET /metrics HTTP/1.1\r\nHost: x\r\n";
    ASSERT_GT(::send(fd, partial, sizeof(partial) - 1, 0), 0);
    slow.push_back(fd);
  }
  httplib::Client client("127.0.0.1", metrics_port());
  client.set_read_timeout(std::chrono::duration<double>(scaled(10.0)));
  const auto started = std::chrono::steady_clock::now();
  const auto res = client.Get("/metrics");
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  for (int fd : slow) ::close(fd);
  ASSERT_TRUE(res) << "no answer with 64 slow clients connected";
  EXPECT_EQ(res->status, 200);
  EXPECT_NE(res->body.find("afr_display"), std::string::npos);
  RecordProperty("metrics_seconds", std::to_string(seconds));
}

TEST_F(DashboardTest, ThePageShowsTheLiveImageAndItsChartsMove) {
  if (!std::filesystem::exists(kChromium)) GTEST_SKIP() << kChromium << " is not installed";
  auto d = display({}, "display.log");
  auto s = sampler({}, "sampler.log");
  ASSERT_TRUE(wait_members(1, scaled(20.0))) << d->log();
  // The page is served by the display itself, and the image is made once a page asks.
  EXPECT_NE(get_text(metrics_port(), "/").find("afr display"), std::string::npos);

  // The display makes images for a few seconds after a page asked for one; headless Chromium
  // runs the page's timers on a virtual clock faster than the display's frames, so one request
  // first, until an image is there.
  ASSERT_TRUE(
      wait_until([&] { return !get_text(metrics_port(), "/image.png").empty(); }, scaled(10.0)));
  // ...and until a stats period has ended (the charts' first point): on a busy machine the
  // sampler can join and the first image come within the display's first second.
  ASSERT_TRUE(wait_until(
      [&] {
        const nlohmann::json h =
            nlohmann::json::parse(get_text(metrics_port(), "/history"), nullptr, false);
        return !h.is_discarded() && h.contains("periods") && !h["periods"].empty();
      },
      scaled(10.0)))
      << d->log();
  const PageLoads first = loads(chromium({"--dump-dom"}, "dom1.log"));
  if (first.images < 0) {
    GTEST_SKIP() << "Chromium did not render the page (cannot start here?): "
                 << chromium({"--dump-dom"}, "dom-again.log").substr(0, 2000);
  }
  EXPECT_GE(first.images, 1);
  EXPECT_GE(first.histories, 1);
  EXPECT_GE(first.periods, 1);
  // A few stats periods later (1 s each) the charts have more, and other, values.
  std::this_thread::sleep_for(std::chrono::duration<double>(scaled(3.0)));
  ASSERT_TRUE(
      wait_until([&] { return !get_text(metrics_port(), "/image.png").empty(); }, scaled(10.0)));
  const std::string dom = chromium({"--dump-dom"}, "dom2.log");
  const PageLoads second = loads(dom);
  // The members' table says what each does (receiving or loading the scene, or sampling).
  EXPECT_NE(dom.find("<td>sampling</td>"), std::string::npos) << dom.substr(0, 4000);
  EXPECT_GE(second.images, 1);
  EXPECT_GT(second.periods, first.periods);
  EXPECT_NE(second.last, first.last);
  const nlohmann::json last = nlohmann::json::parse(
      std::regex_replace(second.last, std::regex("&quot;"), "\""), nullptr, false);
  ASSERT_TRUE(last.is_object()) << second.last;
  EXPECT_EQ(last["members"].get<int>(), 1);
  ASSERT_EQ(last["samplers"].size(), 1u);
  EXPECT_GT(last["samplers"][0]["rate"].get<double>(), 0.0);

  // And what a person sees is not blank: the image (top left) and the charts have content.
  ASSERT_TRUE(
      wait_until([&] { return !get_text(metrics_port(), "/image.png").empty(); }, scaled(10.0)));
  chromium({"--window-size=1300,900", "--screenshot=" + path("shot.png")}, "shot.log");
  ASSERT_TRUE(std::filesystem::exists(path("shot.png")));
  const Image shot = read_image(path("shot.png"));
  ASSERT_EQ(shot.width, 1300);
  const auto spread = [&](int x0, int y0, int x1, int y1) {
    glm::vec3 lo(1e9f), hi(-1e9f);
    for (int y = y0; y < y1; ++y) {
      for (int x = x0; x < x1; ++x) {
        lo = glm::min(lo, shot.at(x, y));
        hi = glm::max(hi, shot.at(x, y));
      }
    }
    return glm::length(hi - lo);
  };
  EXPECT_GT(spread(12, 40, 268, 290), 0.2f);   // the image: not one color
  EXPECT_GT(spread(12, 330, 800, 500), 0.2f);  // the first charts: lines and legends
}

}  // namespace
}  // namespace afr::testing
