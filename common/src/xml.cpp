// The one XML writer (xml.hpp): tinyxml2's printer for the layout, our own escaping for values and text. tinyxml2's
// escaping leaves tabs, newlines and carriage returns raw, which XML readers normalise (CR to LF; in attributes, all
// three to spaces) and which disappear entirely from text that is only white space; as character references they
// survive any reader.
#include "cellwright/common/xml.hpp"

#include <fmt/format.h>
#include <tinyxml2.h>

#include "cellwright/common/error.hpp"

namespace cellwright::xml {
namespace {

// kRaw: white space as is (text with other content keeps it); kAttribute: tabs and newlines as references;
// kAll: every white space character as a reference (text that is only white space).
enum class Space { kRaw, kAttribute, kAll };

std::string escaped(std::string_view value, Space space) {
  std::string out;
  out.reserve(value.size());
  for (char c : value) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\r':
        out += "&#13;";
        break;
      case '\t':
      case '\n':
        if (space != Space::kRaw) {
          out += fmt::format("&#{};", static_cast<int>(c));
        } else {
          out += c;
        }
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          out += fmt::format("&#{};", static_cast<int>(c));
        } else if (c == ' ' && space == Space::kAll) {
          out += "&#32;";
        } else {
          out += c;
        }
        break;
    }
  }
  return out;
}

bool only_white_space(std::string_view s) {
  return s.find_first_not_of(" \t\n\r") == std::string_view::npos;
}

}  // namespace

// tinyxml2's printer to memory, with `indent` spaces per level instead of its four.
class Writer::Printer : public tinyxml2::XMLPrinter {
 public:
  explicit Printer(int indent) : indent_(indent) {}
  void raw(std::string_view s) { Write(s.data(), s.size()); }

 protected:
  void PrintSpace(int depth) override {
    for (int i = 0; i < depth * indent_; ++i) Putc(' ');
  }

 private:
  int indent_;
};

Writer::Writer(int indent) : printer_(std::make_unique<Printer>(indent)) {
  CW_CHECK(indent >= 0, "negative indentation {}", indent);
}

Writer::~Writer() = default;

void Writer::declaration(std::string_view value) {
  printer_->PushDeclaration(std::string(value).c_str());
}

void Writer::open(std::string_view tag) {
  ++elements_;
  open_.push_back({std::string(tag)});
  printer_->OpenElement(open_.back().tag.c_str());
}

void Writer::open(std::string_view tag, const Attributes& attributes) {
  open(tag);
  for (const auto& [name, value] : attributes) attribute(name, value);
}

void Writer::leaf(std::string_view tag, const Attributes& attributes) {
  open(tag, attributes);
  close();
}

void Writer::attribute(std::string_view name, std::string_view value) {
  CW_CHECK(!open_.empty(), "attribute '{}' outside any element", name);
  printer_->raw(" ");
  printer_->raw(name);
  printer_->raw("=\"");
  printer_->raw(escape_attribute(value));
  printer_->raw("\"");
}

void Writer::text(std::string_view value) {
  CW_CHECK(!open_.empty(), "text outside any element");
  printer_->PushText("");  // marks the element as holding text, so that no indentation is added inside it
  printer_->raw(escaped(value, only_white_space(value) ? Space::kAll : Space::kRaw));
  open_.back().text = true;
}

void Writer::text_element(std::string_view tag, std::string_view value) {
  open(tag);
  text(value);
  close();
}

void Writer::close() {
  CW_CHECK(!open_.empty(), "closing an element that was not opened");
  printer_->CloseElement(open_.back().text);
  open_.pop_back();
}

void Writer::comment(std::string_view text) {
  std::string body = " ";
  for (char c : text) {
    if (c == '-' && body.back() == '-') body += ' ';  // "--" ends a comment
    body += c;
  }
  body += ' ';
  printer_->PushComment(body.c_str());
}

std::string Writer::str() const {
  CW_CHECK(open_.empty(), "unclosed element <{}>", open_.empty() ? "" : open_.back().tag);
  return std::string(printer_->CStr(), static_cast<std::size_t>(printer_->CStrSize() - 1));
}

std::string Writer::escape_attribute(std::string_view value) {
  return escaped(value, Space::kAttribute);
}

}  // namespace cellwright::xml
