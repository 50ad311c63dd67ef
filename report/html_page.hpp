// One self-contained HTML page for people: a run's report, a benchmark's. Pictures are
// embedded as data URIs (base64) so the page opens anywhere with nothing beside it; text is
// escaped; the stylesheet prints (white, no player controls, tables kept whole).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace incise::report {

// `text` with &, <, >, " and ' as entities, safe inside an element or a quoted attribute.
std::string html_escaped(const std::string& text);

// The bytes of `file` as base64 (RFC 4648); throws std::runtime_error naming the file if unreadable.
std::string base64_of_file(const std::filesystem::path& file);
std::string base64(const std::string& bytes);

struct TableRow {
  std::vector<std::string> cells;  // plain text, escaped when written
  std::string css_class;           // e.g. "pass" / "fail" (coloured by the stylesheet)
};

class HtmlPage {
 public:
  explicit HtmlPage(std::string title);

  void heading(const std::string& text, int level = 2);
  void paragraph(const std::string& text);
  // Text laid out by its writer (a benchmark's summary), kept as is in a monospaced block.
  void preformatted(const std::string& text);
  // A notice of something missing (no gnuplot, no frames): said on the page, not an error.
  void note(const std::string& text);
  // Trusted markup written as is (the player, the video tag).
  void raw(const std::string& html);
  // A PNG embedded as a data URI, with `id` for the layout hook (see layout_script); a
  // missing file becomes a note naming it.
  void embedded_png(const std::filesystem::path& png, const std::string& alt, const std::string& id);
  void table(const std::vector<std::string>& header, const std::vector<TableRow>& rows);

  std::string html() const;
  // Writes the page; throws std::runtime_error naming the file if it cannot.
  void write(const std::filesystem::path& file) const;

 private:
  std::string title_;
  std::string body_;
};

}  // namespace incise::report
