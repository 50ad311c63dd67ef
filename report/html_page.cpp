#include "report/html_page.hpp"

#include <fstream>
#include <stdexcept>

namespace incise::report {

namespace {

// On screen the page is off-white and the plots white, so a screenshot shows where each plot
// is; printed, everything is white and the player's controls are hidden.
constexpr const char* kStyle = R"(
body { font: 15px/1.45 sans-serif; color: #111; background: #f3f2ee; margin: 0 auto; max-width: 1100px; padding: 1em 1.5em; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; border-bottom: 1px solid #bbb; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.5em 0; background: #fff; }
th, td { border: 1px solid #bbb; padding: 0.2em 0.6em; text-align: left; font-variant-numeric: tabular-nums; }
th { background: #e4e2dc; }
tr.pass td { background: #d9f2d9; }
tr.fail td { background: #f8d0d0; font-weight: bold; }
img.plot { display: block; max-width: 100%; height: auto; background: #fff; margin: 0.6em 0; border: 1px solid #ccc; }
pre { background: #fff; border: 1px solid #ccc; padding: 0.5em; font-size: 0.85em; white-space: pre-wrap; }
.note { background: #fff6d5; border-left: 4px solid #d9a400; padding: 0.3em 0.7em; }
.strip { display: flex; flex-wrap: wrap; gap: 4px; }
.strip figure { margin: 0; font-size: 0.8em; text-align: center; }
.strip img { width: 128px; height: auto; border: 1px solid #999; }
.player img { max-width: 100%; border: 1px solid #999; background: #000; }
.player input[type=range] { width: 60%; vertical-align: middle; }
video { max-width: 100%; background: #000; }
.media { display: flex; flex-wrap: wrap; gap: 1.5em; align-items: flex-start; }
.media > div { flex: 1 1 400px; min-width: 0; }
@media print {
  body { background: #fff; max-width: none; font-size: 11pt; }
  .player .controls, video { display: none; }
  img.plot, table, figure { page-break-inside: avoid; break-inside: avoid; }
  h2 { page-break-after: avoid; break-after: avoid; }
  tr.pass td, tr.fail td, th { -webkit-print-color-adjust: exact; print-color-adjust: exact; }
}
)";

// A test hook: opened as page.html#layout, the page lists where each plot landed
// (id x y width height, CSS pixels) in <pre id="layout">, so a headless browser's screenshot
// can be checked region by region (tests/report/).
constexpr const char* kLayoutScript = R"(
window.addEventListener('load', function () {
  if (location.hash !== '#layout') return;
  var lines = [];
  document.querySelectorAll('img.plot').forEach(function (img) {
    var r = img.getBoundingClientRect();
    lines.push([img.id, Math.round(r.left + scrollX), Math.round(r.top + scrollY), Math.round(r.width), Math.round(r.height)].join(' '));
  });
  var pre = document.createElement('pre');
  pre.id = 'layout';
  pre.textContent = lines.join('\n');
  document.body.appendChild(pre);
});
)";

}  // namespace

std::string html_escaped(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

HtmlPage::HtmlPage(std::string title) : title_(std::move(title)) {}

void HtmlPage::heading(const std::string& text, int level) {
  const char digit = static_cast<char>('0' + (level < 1 ? 1 : level > 4 ? 4 : level));
  body_.append("<h").push_back(digit);
  body_.append(">").append(html_escaped(text)).append("</h").push_back(digit);
  body_.append(">\n");
}

void HtmlPage::paragraph(const std::string& text) { body_ += "<p>" + html_escaped(text) + "</p>\n"; }

void HtmlPage::preformatted(const std::string& text) { body_ += "<pre>" + html_escaped(text) + "</pre>\n"; }

void HtmlPage::note(const std::string& text) { body_ += "<p class=\"note\">" + html_escaped(text) + "</p>\n"; }

void HtmlPage::raw(const std::string& html) { body_ += html + "\n"; }

void HtmlPage::embedded_png(const std::filesystem::path& png, const std::string& alt, const std::string& id) {
  if (!std::filesystem::exists(png)) {
    note(alt + ": not drawn (" + png.filename().string() + " is missing)");
    return;
  }
  body_ += "<img class=\"plot\" id=\"" + html_escaped(id) + "\" alt=\"" + html_escaped(alt) +
           "\" src=\"data:image/png;base64," + base64_of_file(png) + "\">\n";
}

void HtmlPage::table(const std::vector<std::string>& header, const std::vector<TableRow>& rows) {
  body_ += "<table>\n<tr>";
  for (const auto& h : header) body_ += "<th>" + html_escaped(h) + "</th>";
  body_ += "</tr>\n";
  for (const auto& row : rows) {
    body_ += row.css_class.empty() ? "<tr>" : "<tr class=\"" + html_escaped(row.css_class) + "\">";
    for (const auto& cell : row.cells) body_ += "<td>" + html_escaped(cell) + "</td>";
    body_ += "</tr>\n";
  }
  body_ += "</table>\n";
}

std::string HtmlPage::html() const {
  return "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" + html_escaped(title_) +
         "</title>\n<style>" + kStyle + "</style>\n<script>" + kLayoutScript + "</script>\n</head>\n<body>\n<h1>" +
         html_escaped(title_) + "</h1>\n" + body_ + "</body>\n</html>\n";
}

void HtmlPage::write(const std::filesystem::path& file) const {
  std::ofstream out(file, std::ios::binary);
  out << html();
  if (!out) throw std::runtime_error(file.string() + ": cannot write");
}

}  // namespace incise::report
