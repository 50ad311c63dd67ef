// Checks a headless browser's screenshot of report.html: the page is not uniform, and each
// plot's region (from the page's #layout hook: "id x y width height" per line) differs from
// the page background and holds dark pixels (axes, labels, curves), i.e. a plot was drawn
// there rather than a broken-image box or nothing.
//   report_screenshot_check SHOT.png LAYOUT.txt MIN_PLOTS
#define STB_IMAGE_IMPLEMENTATION
#include <stb/stb_image.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>

namespace {

struct Image {
  int width = 0, height = 0;
  unsigned char* pixels = nullptr;  // RGB
  unsigned rgb(int x, int y) const {
    const unsigned char* p = pixels + 3 * (static_cast<long>(y) * width + x);
    return (p[0] << 16) | (p[1] << 8) | p[2];
  }
};

double luma(unsigned rgb) { return 0.299 * (rgb >> 16) + 0.587 * ((rgb >> 8) & 255) + 0.114 * (rgb & 255); }

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: report_screenshot_check SHOT.png LAYOUT.txt MIN_PLOTS\n");
    return 2;
  }
  Image image;
  int channels = 0;
  image.pixels = stbi_load(argv[1], &image.width, &image.height, &channels, 3);
  if (!image.pixels) {
    std::fprintf(stderr, "%s: not a readable PNG (%s)\n", argv[1], stbi_failure_reason());
    return 1;
  }
  std::map<unsigned, long> counts;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) ++counts[image.rgb(x, y)];
  unsigned background = 0;
  long most = 0;
  for (const auto& [colour, n] : counts)
    if (n > most) most = n, background = colour;
  std::printf("%s: %dx%d, %zu colours, background #%06x on %.1f %% of the page\n", argv[1], image.width, image.height,
              counts.size(), background, 100.0 * most / (static_cast<double>(image.width) * image.height));
  int failures = 0;
  if (counts.size() < 64) {
    std::printf("FAIL: the screenshot is (nearly) uniform: %zu colours\n", counts.size());
    ++failures;
  }
  std::ifstream layout(argv[2]);
  if (!layout) {
    std::fprintf(stderr, "%s: cannot read\n", argv[2]);
    return 1;
  }
  int checked = 0;
  std::string line;
  while (std::getline(layout, line)) {
    std::istringstream fields(line);
    std::string id;
    int x = 0, y = 0, w = 0, h = 0;
    if (!(fields >> id >> x >> y >> w >> h)) continue;
    if (w < 50 || h < 50 || x < 0 || y < 0 || x + w > image.width || y + h > image.height) {
      std::printf("%s: %dx%d at (%d, %d) is outside the screenshot: not checked\n", id.c_str(), w, h, x, y);
      continue;
    }
    long differ = 0, dark = 0;
    std::set<unsigned> colours;
    // The border pixel is the image's frame, not the plot: look inside it.
    for (int j = y + 2; j < y + h - 2; ++j)
      for (int i = x + 2; i < x + w - 2; ++i) {
        const unsigned c = image.rgb(i, j);
        differ += c != background;
        dark += luma(c) < 100;
        if (colours.size() < 1000) colours.insert(c);
      }
    const double area = static_cast<double>(w - 4) * (h - 4);
    const bool ok = differ / area > 0.8 && dark / area > 0.003 && colours.size() >= 8;
    std::printf("%s %s: %dx%d at (%d, %d): %.1f %% differ from the background, %.2f %% dark, %zu colours\n",
                ok ? "ok  " : "FAIL", id.c_str(), w, h, x, y, 100 * differ / area, 100 * dark / area, colours.size());
    failures += ok ? 0 : 1;
    ++checked;
  }
  stbi_image_free(image.pixels);
  const int min_plots = std::stoi(argv[3]);
  if (checked < min_plots) {
    std::printf("FAIL: %d plots checked, expected at least %d\n", checked, min_plots);
    ++failures;
  }
  return failures ? 1 : 0;
}
