// Synthetic event tables for the nanocube's scale trend (issue 18): N rows of
// `time,kind,delay_min,lat,lon` as CSV on stdout: points around 1,000 centres of Zipf weights,
// times over 2001 with a daily and a weekly cycle, a Zipf category of 500 labels, a numeric
// column. Usage: kiln_make_events ROWS [SEED] > events.csv
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <vector>

int main(int argc, char** argv) {
  const bool help = argc >= 2 && (!std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h"));
  if (help) {
    std::printf(
        "usage: %s ROWS [SEED] > events.csv\n"
        "Synthetic events: clustered points, seasonal times over 2001, Zipf labels.\n",
        argv[0]);
    return 0;
  }
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s ROWS [SEED] > events.csv\n", argv[0]);
    return 2;
  }
  const unsigned long long rows = std::strtoull(argv[1], nullptr, 10);
  std::mt19937_64 rng(argc > 2 ? std::strtoull(argv[2], nullptr, 10) : 1);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> n(0, 1);
  // Zipf(1) weights as a cumulative table, shared by centres and labels.
  auto zipf = [](int k) {
    std::vector<double> cdf(static_cast<std::size_t>(k), 0.0);
    double total = 0;
    for (int i = 0; i < k; ++i) cdf[std::size_t(i)] = total += 1.0 / (i + 1);
    for (double& c : cdf) c /= total;
    return cdf;
  };
  const auto centre_cdf = zipf(1000), label_cdf = zipf(500);
  auto pick = [&](const std::vector<double>& cdf) {
    return std::size_t(std::lower_bound(cdf.begin(), cdf.end(), u(rng)) - cdf.begin());
  };
  std::vector<std::pair<double, double>> centres;
  for (int i = 0; i < 1000; ++i) centres.emplace_back(25 + 24 * u(rng), -124 + 56 * u(rng));
  std::printf("time,kind,delay_min,lat,lon\n");
  const long long start = 978307200;  // 2001-01-01T00:00Z
  constexpr double kPi = 3.14159265358979323846;
  for (unsigned long long r = 0; r < rows; ++r) {
    const auto& c = centres[std::min<std::size_t>(pick(centre_cdf), 999)];
    const double lat = std::clamp(c.first + 0.05 * n(rng), -85.0, 85.0);
    const double lon = std::clamp(c.second + 0.05 * n(rng), -180.0, 180.0);
    long long t = 0;
    for (;;) {  // rejection sampling: busy days and weekdays
      t = start + (long long)(u(rng) * 365 * 86400);
      const double day = std::sin(2 * kPi * double(t % 86400) / 86400 - kPi / 2);
      const double week = (t / 86400 + 1) % 7 < 5 ? 1.0 : 0.6;
      if (u(rng) < week * (0.6 + 0.4 * day)) break;
    }
    std::printf("%lld,L%03zu,%d,%.6f,%.6f\n", t, std::min<std::size_t>(pick(label_cdf), 499),
                int(std::lround(10 + 30 * n(rng))), lat, lon);
  }
  return 0;
}
