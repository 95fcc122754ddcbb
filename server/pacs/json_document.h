// JSON from a PACS (RFC 8259, strictly), parsed with bounds no text can get
// past: nesting depth, the number of values (so memory is known before it is
// taken: at most max_values nodes and the text's own size in strings), and
// time (one pass, linear in the text, checking `cancel` as it goes). A text
// outside the grammar (single quotes, comments, trailing commas, NaN) is
// refused, never guessed at, so no other parser sees what this one did not.
#pragma once

#include <atomic>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace cinevol::pacs {

// A text that is not JSON, or passes a limit: what and where.
class JsonError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

struct JsonLimits {
  int max_depth = 32;                      // arrays and objects inside each other
  std::size_t max_values = std::size_t{1} << 20;  // values of every kind, members' names not counted
};

class JsonDocument {
 public:
  enum class Kind : std::uint8_t { kNull, kFalse, kTrue, kNumber, kString, kArray, kObject };

 private:
  static constexpr std::uint32_t kNone = ~std::uint32_t{0};
  struct Node {
    Kind kind = Kind::kNull;
    std::uint32_t first = kNone, next = kNone;  // an array's or object's first child; the parent's next one
    std::uint32_t name_at = 0, name_size = 0;   // a member's name in strings_
    std::uint32_t text_at = 0, text_size = 0;   // a string's text in strings_
    double number = 0;
  };

 public:
  // One value of the document; cheap to copy, valid while the document lives.
  class Ref {
   public:
    Ref() = default;  // invalid: what a missing member reads as
    bool valid() const { return doc_ != nullptr; }
    // kNull for an invalid Ref.
    Kind kind() const { return valid() ? node().kind : Kind::kNull; }
    bool is(Kind k) const { return kind() == k; }
    // A string's text (UTF-8, escapes decoded); empty for other kinds.
    std::string_view text() const;
    // A number's value; 0 for other kinds.
    double number() const { return is(Kind::kNumber) ? node().number : 0.0; }
    // An array's items or an object's member values, in order.
    std::vector<Ref> children() const;
    // An object's first member named `name`; an invalid Ref when there is none.
    Ref member(std::string_view name) const;

   private:
    friend class JsonDocument;
    Ref(const JsonDocument* doc, std::uint32_t index) : doc_(doc), index_(index) {}
    const Node& node() const { return doc_->nodes_[index_]; }
    const JsonDocument* doc_ = nullptr;
    std::uint32_t index_ = 0;
  };

  JsonDocument() = default;
  // Throws JsonError for a text that is not one JSON value within `limits`,
  // Cancelled (core/error.h) once `cancel` is raised.
  static JsonDocument Parse(std::string_view text, const JsonLimits& limits = {},
                            const std::atomic<bool>* cancel = nullptr);

  Ref root() const { return Ref(this, 0); }

 private:
  friend class JsonParser;
  std::vector<Node> nodes_;
  std::string strings_;  // every decoded string and member name, end to end
};

}  // namespace cinevol::pacs
