// JsonDocument: a recursive-descent parser over RFC 8259's grammar, one
// pass, every step bounded (json_document.h).
#include "pacs/json_document.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>

#include "core/error.h"

namespace cinevol::pacs {

namespace {
// How often, in bytes of text, the parser looks at its cancel flag.
constexpr std::size_t kCancelCheckBytes = std::size_t{1} << 16;
}  // namespace

class JsonParser {
 public:
  JsonParser(std::string_view text, const JsonLimits& limits, const std::atomic<bool>* cancel, JsonDocument& doc)
      : text_(text), limits_(limits), cancel_(cancel), doc_(doc) {}

  void Run() {
    if (text_.size() >= JsonDocument::kNone) Fail("the text is larger than 4 GiB");
    SkipSpace();
    Value(0);
    SkipSpace();
    if (at_ != text_.size()) Fail("text after the value");
  }

 private:
  [[noreturn]] void Fail(std::string_view what) const {
    throw JsonError(fmt::format("not JSON: {} at byte {}", what, at_));
  }

  char Peek() const { return at_ < text_.size() ? text_[at_] : '\0'; }
  bool AtEnd() const { return at_ >= text_.size(); }

  void SkipSpace() {
    while (!AtEnd() && (Peek() == ' ' || Peek() == '\t' || Peek() == '\n' || Peek() == '\r')) ++at_;
  }

  void Expect(char c) {
    if (Peek() != c || AtEnd()) Fail(fmt::format("'{}' expected", c));
    ++at_;
  }

  void CheckCancel() {
    if (at_ < next_cancel_check_) return;
    next_cancel_check_ = at_ + kCancelCheckBytes;
    if (cancel_ != nullptr && cancel_->load(std::memory_order_relaxed)) throw Cancelled("reading a JSON answer was cancelled");
  }

  // A new node, counted against max_values before it is made.
  std::uint32_t NewNode(JsonDocument::Kind kind) {
    if (doc_.nodes_.size() >= limits_.max_values) Fail(fmt::format("more than {} values", limits_.max_values));
    doc_.nodes_.push_back({});
    doc_.nodes_.back().kind = kind;
    return std::uint32_t(doc_.nodes_.size() - 1);
  }

  std::uint32_t Value(int depth) {
    CheckCancel();
    switch (Peek()) {
      case '{':
        return Container(depth, JsonDocument::Kind::kObject, '}');
      case '[':
        return Container(depth, JsonDocument::Kind::kArray, ']');
      case '"': {
        const std::uint32_t node = NewNode(JsonDocument::Kind::kString);
        String(doc_.nodes_[node].text_at, doc_.nodes_[node].text_size);
        return node;
      }
      case 't':
        return Literal("true", JsonDocument::Kind::kTrue);
      case 'f':
        return Literal("false", JsonDocument::Kind::kFalse);
      case 'n':
        return Literal("null", JsonDocument::Kind::kNull);
      default:
        if (Peek() == '-' || (Peek() >= '0' && Peek() <= '9')) return Number();
        if (AtEnd()) Fail("a value expected, not the end");
        const auto c = static_cast<unsigned char>(Peek());
        Fail(c >= 0x20 && c < 0x7f ? fmt::format("a value expected, not '{}'", char(c))
                                   : fmt::format("a value expected, not byte {:#04x}", c));
    }
  }

  std::uint32_t Literal(std::string_view word, JsonDocument::Kind kind) {
    if (text_.substr(at_, word.size()) != word) Fail("an unknown word");
    at_ += word.size();
    return NewNode(kind);
  }

  // -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?, checked, then read by from_chars.
  std::uint32_t Number() {
    const std::size_t start = at_;
    auto digits = [&] {
      const std::size_t from = at_;
      while (!AtEnd() && Peek() >= '0' && Peek() <= '9') ++at_;
      if (at_ == from) Fail("a digit expected");
    };
    if (Peek() == '-') ++at_;
    if (Peek() == '0') {
      ++at_;
    } else {
      digits();
    }
    if (Peek() == '.') ++at_, digits();
    if (Peek() == 'e' || Peek() == 'E') {
      ++at_;
      if (Peek() == '+' || Peek() == '-') ++at_;
      digits();
    }
    double value = 0;
    const auto [end, error] = std::from_chars(text_.data() + start, text_.data() + at_, value);
    // Past a double's range: infinite, which readers take as absent.
    if (error == std::errc::result_out_of_range) value = text_[start] == '-' ? -INFINITY : INFINITY;
    const std::uint32_t node = NewNode(JsonDocument::Kind::kNumber);
    doc_.nodes_[node].number = value;
    return node;
  }

  // An array or object: its children linked in order.
  std::uint32_t Container(int depth, JsonDocument::Kind kind, char close) {
    if (depth + 1 > limits_.max_depth) Fail(fmt::format("nesting deeper than {} levels", limits_.max_depth));
    const std::uint32_t node = NewNode(kind);
    ++at_;
    SkipSpace();
    if (Peek() == close && !AtEnd()) {
      ++at_;
      return node;
    }
    std::uint32_t last = JsonDocument::kNone;
    for (;;) {
      std::uint32_t name_at = 0, name_size = 0;
      if (kind == JsonDocument::Kind::kObject) {
        if (Peek() != '"') Fail("a member name expected");
        String(name_at, name_size);
        SkipSpace();
        Expect(':');
        SkipSpace();
      }
      const std::uint32_t child = Value(depth + 1);
      doc_.nodes_[child].name_at = name_at;
      doc_.nodes_[child].name_size = name_size;
      (last == JsonDocument::kNone ? doc_.nodes_[node].first : doc_.nodes_[last].next) = child;
      last = child;
      SkipSpace();
      if (Peek() == ',' && !AtEnd()) {
        ++at_;
        SkipSpace();
        continue;
      }
      Expect(close);
      return node;
    }
  }

  // A string, decoded into the document's strings; `at` and `size` say where.
  void String(std::uint32_t& at, std::uint32_t& size) {
    ++at_;  // the opening quote
    std::string& out = doc_.strings_;
    const std::size_t begin = out.size();
    for (;;) {
      if (AtEnd()) Fail("a string without its closing quote");
      const unsigned char c = static_cast<unsigned char>(text_[at_]);
      if (c == '"') break;
      if (c < 0x20) Fail("a control character in a string");
      if (c == '\\') {
        Escape(out);
      } else {
        out.push_back(char(c));
        ++at_;
      }
      CheckCancel();
    }
    ++at_;
    at = std::uint32_t(begin);
    size = std::uint32_t(out.size() - begin);
  }

  unsigned Hex4() {
    if (at_ + 4 > text_.size()) Fail("a \\u escape without four hex digits");
    unsigned value = 0;
    for (int i = 0; i < 4; ++i) {
      const char c = text_[at_++];
      const int digit = c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
      if (digit < 0) Fail("a \\u escape without four hex digits");
      value = value * 16 + unsigned(digit);
    }
    return value;
  }

  void Escape(std::string& out) {
    ++at_;  // the backslash
    if (AtEnd()) Fail("a string without its closing quote");
    const char c = text_[at_++];
    switch (c) {
      case '"': out.push_back('"'); return;
      case '\\': out.push_back('\\'); return;
      case '/': out.push_back('/'); return;
      case 'b': out.push_back('\b'); return;
      case 'f': out.push_back('\f'); return;
      case 'n': out.push_back('\n'); return;
      case 'r': out.push_back('\r'); return;
      case 't': out.push_back('\t'); return;
      case 'u': break;
      default: Fail("an unknown escape");
    }
    unsigned code = Hex4();
    // A surrogate pair is one character; a lone surrogate is none, and becomes U+FFFD.
    if (code >= 0xD800 && code < 0xDC00 && text_.substr(at_, 2) == "\\u") {
      const std::size_t mark = at_;
      at_ += 2;
      const unsigned low = Hex4();
      if (low >= 0xDC00 && low < 0xE000) {
        code = 0x10000 + ((code - 0xD800) << 10) + (low - 0xDC00);
      } else {
        at_ = mark;
      }
    }
    if (code >= 0xD800 && code < 0xE000) code = 0xFFFD;
    AppendUtf8(out, code);
  }

  static void AppendUtf8(std::string& out, unsigned code) {
    if (code < 0x80) {
      out.push_back(char(code));
    } else if (code < 0x800) {
      out.push_back(char(0xC0 | (code >> 6)));
      out.push_back(char(0x80 | (code & 0x3F)));
    } else if (code < 0x10000) {
      out.push_back(char(0xE0 | (code >> 12)));
      out.push_back(char(0x80 | ((code >> 6) & 0x3F)));
      out.push_back(char(0x80 | (code & 0x3F)));
    } else {
      out.push_back(char(0xF0 | (code >> 18)));
      out.push_back(char(0x80 | ((code >> 12) & 0x3F)));
      out.push_back(char(0x80 | ((code >> 6) & 0x3F)));
      out.push_back(char(0x80 | (code & 0x3F)));
    }
  }

  std::string_view text_;
  const JsonLimits& limits_;
  const std::atomic<bool>* cancel_;
  JsonDocument& doc_;
  std::size_t at_ = 0;
  std::size_t next_cancel_check_ = 0;
};

JsonDocument JsonDocument::Parse(std::string_view text, const JsonLimits& limits, const std::atomic<bool>* cancel) {
  JsonDocument doc;
  JsonParser(text, limits, cancel, doc).Run();
  return doc;
}

std::string_view JsonDocument::Ref::text() const {
  if (!is(Kind::kString)) return {};
  const Node& n = node();
  return std::string_view(doc_->strings_).substr(n.text_at, n.text_size);
}

std::vector<JsonDocument::Ref> JsonDocument::Ref::children() const {
  std::vector<Ref> refs;
  if (!is(Kind::kArray) && !is(Kind::kObject)) return refs;
  const Node& n = node();
  for (std::uint32_t child = n.first; child != kNone; child = doc_->nodes_[child].next) refs.push_back({doc_, child});
  return refs;
}

JsonDocument::Ref JsonDocument::Ref::member(std::string_view name) const {
  if (!is(Kind::kObject)) return {};
  const Node& n = node();
  for (std::uint32_t child = n.first; child != kNone; child = doc_->nodes_[child].next) {
    const Node& c = doc_->nodes_[child];
    if (std::string_view(doc_->strings_).substr(c.name_at, c.name_size) == name) return {doc_, child};
  }
  return {};
}

}  // namespace cinevol::pacs
