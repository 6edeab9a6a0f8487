// Captions and the heatmap legend, with Sean Barrett's stb_easy_font (Debian's libstb-dev): it
// turns text into axis-aligned quads in font pixels, which are filled here as rectangles.
#include <algorithm>
#include <string>

#include "kiln/tools/render.hpp"

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"  // the header's spacing setter is unused
#include <stb/stb_easy_font.h>
#pragma GCC diagnostic pop

namespace kiln::render {

namespace {

// The font indexes a table by (character - 32) for 32..126: anything else becomes '?', so no
// text can read outside it.
std::string printable(std::string_view text) {
  std::string s(text);
  for (char& c : s)
    if (c < 32 || c > 126) c = '?';
  return s;
}

void fill(Image& image, int x0, int y0, int x1, int y1, Rgb colour) {
  x0 = std::max(x0, 0), y0 = std::max(y0, 0);
  x1 = std::min(x1, int(image.width)), y1 = std::min(y1, int(image.height));
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) image.at(std::uint32_t(x), std::uint32_t(y)) = colour;
}

constexpr Rgb kText{240, 240, 240};
constexpr int kPad = 4;

// Text with stb_easy_font, each font pixel drawn as a `scale` x `scale` block; clipped.
int text_width(std::string_view text, int scale) {
  std::string s = printable(text);
  return stb_easy_font_width(s.data()) * scale;
}

int text_height(std::string_view text, int scale) {
  std::string s = printable(text);
  // stb_easy_font_height counts 12 font pixels a line; glyphs use the top 9 of them.
  return (stb_easy_font_height(s.data()) - 3) * scale;
}

void draw_text(Image& image, int x, int y, std::string_view text, Rgb colour, int scale) {
  std::string s = printable(text);
  struct Vertex {
    float x, y, z;
    unsigned char rgba[4];
  };
  static_assert(sizeof(Vertex) == 16);  // the layout stb_easy_font writes
  // At most about 30 quads a character; the font stops when the buffer is full.
  std::vector<Vertex> quads(4 * 32 * (s.size() + 1));
  const int count = stb_easy_font_print(0, 0, s.data(), nullptr, quads.data(),
                                        int(quads.size() * sizeof(Vertex)));
  for (int q = 0; q < count; ++q) {
    const Vertex& a = quads[std::size_t(q) * 4];
    const Vertex& c = quads[std::size_t(q) * 4 + 2];  // the opposite corner
    fill(image, x + int(a.x) * scale, y + int(a.y) * scale, x + int(c.x) * scale,
         y + int(c.y) * scale, colour);
  }
}

// Fills the rectangle (clipped) with the dark backing of captions and the legend, so overlaid
// text stays readable on any picture (opaque: one colour, which keeps heatmaps palettable).
void backing(Image& image, int x, int y, int w, int h) {
  fill(image, x, y, x + w, y + h, Rgb{12, 13, 18});
}

}  // namespace

void draw_caption(Image& image, int x0, std::string_view text) {
  const int scale = image.height >= 300 ? 2 : 1;
  const int w = text_width(text, scale), h = text_height(text, scale);
  backing(image, x0, 0, w + 2 * kPad, h + 2 * kPad);
  draw_text(image, x0 + kPad, kPad, text, kText, scale);
}

void draw_legend(Image& image, std::uint32_t heat_scale, bool clamped, std::string_view title) {
  // Too small an image to hold a readable legend: the numbers are on stdout anyway.
  if (image.width < 64 || image.height < 48) return;
  const int scale = image.height >= 300 ? 2 : 1;
  const int bar_w = std::min(int(image.width) - 4 * kPad, 256 * scale);
  const int bar_h = 6 * scale;
  const std::string labels[3] = {"0", std::to_string((heat_scale + 1) / 2),
                                 std::to_string(heat_scale) + (clamped ? "+" : "")};
  const int line = text_height("0", scale);
  const int box_w = std::max(bar_w, text_width(title, scale)) + 2 * kPad;
  const int box_h = line + kPad + bar_h + kPad + line + 2 * kPad;
  const int box_x = (int(image.width) - box_w) / 2, box_y = int(image.height) - box_h;
  backing(image, box_x, box_y, box_w, box_h);
  const int bar_x = (int(image.width) - bar_w) / 2;
  const int title_y = box_y + kPad, bar_y = title_y + line + kPad;
  draw_text(image, (int(image.width) - text_width(title, scale)) / 2, title_y, title, kText, scale);
  for (int i = 0; i < bar_w; ++i) {
    // The cost at this column, rounded: the bar shows exactly the colours of the image.
    const std::uint64_t cost =
        bar_w > 1 ? (std::uint64_t(i) * heat_scale + std::uint64_t(bar_w - 1) / 2) /
                        std::uint64_t(bar_w - 1)
                  : 0;
    fill(image, bar_x + i, bar_y, bar_x + i + 1, bar_y + bar_h,
         heat_colour(std::uint32_t(cost), heat_scale));
  }
  // Labels under the bar's left end, middle and right end (kept inside the bar's span).
  const int label_y = bar_y + bar_h + kPad;
  const int anchors[3] = {bar_x, bar_x + bar_w / 2, bar_x + bar_w};
  for (int i = 0; i < 3; ++i) {
    const int w = text_width(labels[i], scale);
    // Kept inside the bar; a label wider than the bar starts at its left end.
    const int x = std::max(bar_x, std::min(anchors[i] - w / 2, bar_x + bar_w - w));
    fill(image, anchors[i] - scale / 2 - (i == 2 ? 1 : 0), bar_y + bar_h,
         anchors[i] + (scale + 1) / 2 - (i == 2 ? 1 : 0), bar_y + bar_h + kPad / 2, kText);
    draw_text(image, x, label_y, labels[i], kText, scale);
  }
}

}  // namespace kiln::render
