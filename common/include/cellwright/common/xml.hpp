// Writing XML documents (PNML nets, MuJoCo's MJCF): the project's one XML writer, on tinyxml2's XMLPrinter, with
// escaping that survives any XML reader.
//
// Layout: each element starts on a line of its own, indented by `indent` spaces per level; an element without
// children is written "<tag a="v"/>"; an element holding text is written on one line, "<tag>text</tag>"; the
// document ends with a newline (unless its root element holds text, as tinyxml2 writes it).
//
// Escaping (attribute values and text): & < > " become entities; carriage returns and other control characters
// become character references. In attribute values tabs and newlines do too (readers would turn them into spaces),
// and so does every white space character of text that is only white space (readers would drop it). Comments cannot
// hold "--": a space is put between two dashes.
//
// Thread safety: a Writer is a plain object for one thread at a time.
#pragma once

#include <cstddef>
#include <deque>
#include <memory>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

namespace cellwright::xml {

// Attributes in the order they are written.
using Attributes = std::vector<std::pair<std::string, std::string>>;

class Writer {
 public:
  explicit Writer(int indent = 4);
  ~Writer();
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  // <?value?>, e.g. declaration("xml version=\"1.0\" encoding=\"UTF-8\""); before the first element.
  void declaration(std::string_view value);
  // Starts an element; attribute() and text() then go into it until close().
  void open(std::string_view tag);
  void open(std::string_view tag, const Attributes& attributes);
  // An element without children: open(tag, attributes) then close().
  void leaf(std::string_view tag, const Attributes& attributes = {});
  // An attribute of the element just opened (before any child or text), its value escaped.
  void attribute(std::string_view name, std::string_view value);
  template <typename Integer,
            typename = std::enable_if_t<std::is_integral_v<Integer> && !std::is_same_v<Integer, bool>>>
  void attribute(std::string_view name, Integer value) {
    attribute(name, std::string_view(std::to_string(value)));
  }
  // Text content of the element last opened, escaped; its closing tag then follows on the same line.
  void text(std::string_view value);
  // <tag>text</tag>: open(tag), text(value), close().
  void text_element(std::string_view tag, std::string_view value);
  // Closes the element last opened. CW_CHECK that one is open.
  void close();
  // <!-- text --> on a line of its own.
  void comment(std::string_view text);

  // The document. CW_CHECK that every element is closed.
  std::string str() const;
  // How many elements have been started so far: the next element is the document's element number elements()
  // (from 0) in document order, as a reader walking the document meets them (to find an element again by a line
  // number a reader of the document reports).
  std::size_t elements() const { return elements_; }

  // An attribute value as attribute() writes it (without the quotes).
  static std::string escape_attribute(std::string_view value);

 private:
  class Printer;
  struct Open {
    std::string tag;  // the printer keeps a pointer to it until the element is closed: a deque never moves it
    bool text = false;
  };
  std::unique_ptr<Printer> printer_;
  std::deque<Open> open_;  // the open elements, outermost first
  std::size_t elements_ = 0;
};

}  // namespace cellwright::xml
