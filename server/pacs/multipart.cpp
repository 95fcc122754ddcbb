// multipart/related, read strictly and written simply.
#include "pacs/multipart.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <random>

namespace cinevol::pacs {
namespace {

constexpr std::size_t kMaxPartHeaderBytes = 16 * 1024;

std::string Lower(std::string_view text) {
  std::string lower(text);
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  return lower;
}

std::string_view Trim(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t')) text.remove_suffix(1);
  return text;
}

// The `;`-separated pieces of a header value, with quoted strings kept whole
// (a quoted parameter may hold `;`) and their quotes and escapes removed.
std::vector<std::string> HeaderPieces(std::string_view value) {
  std::vector<std::string> pieces(1);
  bool quoted = false;
  for (std::size_t i = 0; i < value.size(); ++i) {
    const char c = value[i];
    if (quoted && c == '\\' && i + 1 < value.size()) {
      pieces.back() += value[++i];
    } else if (c == '"') {
      quoted = !quoted;
    } else if (c == ';' && !quoted) {
      pieces.emplace_back();
    } else {
      pieces.back() += c;
    }
  }
  if (quoted) throw MultipartError("Content-Type has an unterminated quoted string");
  for (std::string& piece : pieces) piece = std::string(Trim(piece));
  return pieces;
}

// RFC 2046's bchars: what a boundary may be made of (a space, but not at its end).
bool IsValidBoundary(std::string_view boundary) {
  if (boundary.empty() || boundary.size() > 70 || boundary.back() == ' ') return false;
  return std::all_of(boundary.begin(), boundary.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) ||
           std::string_view("'()+_,-./:=? ").find(c) != std::string_view::npos;
  });
}

// The position after the first delimiter: at the very start of the body, or
// after a preamble that ends in CRLF.
std::size_t AfterFirstDelimiter(std::string_view body, std::string_view boundary) {
  const std::string dash_boundary = "--" + std::string(boundary);
  if (body.substr(0, dash_boundary.size()) == dash_boundary) return dash_boundary.size();
  const std::size_t found = body.find("\r\n" + dash_boundary);
  if (found == std::string_view::npos) throw MultipartError("the body does not hold its boundary");
  return found + 2 + dash_boundary.size();
}

// After a delimiter: linear white space, then CRLF; returns where the part starts.
std::size_t AfterDelimiterLine(std::string_view body, std::size_t position) {
  while (position < body.size() && (body[position] == ' ' || body[position] == '\t')) ++position;
  if (position + 2 > body.size()) throw MultipartError("the body is truncated after a boundary");
  if (body.substr(position, 2) != "\r\n") throw MultipartError("a boundary line does not end in CRLF");
  return position + 2;
}

}  // namespace

std::string MultipartBoundary(std::string_view content_type) {
  const std::vector<std::string> pieces = HeaderPieces(content_type);
  if (Lower(pieces.front()) != "multipart/related") {
    throw MultipartError("the Content-Type is not multipart/related");
  }
  for (std::size_t i = 1; i < pieces.size(); ++i) {
    const std::size_t equals = pieces[i].find('=');
    if (equals == std::string::npos || Lower(Trim(std::string_view(pieces[i]).substr(0, equals))) != "boundary") {
      continue;
    }
    const std::string boundary(Trim(std::string_view(pieces[i]).substr(equals + 1)));
    if (!IsValidBoundary(boundary)) throw MultipartError("the Content-Type's boundary is not a valid one");
    return boundary;
  }
  throw MultipartError("the Content-Type has no boundary");
}

std::string PartMediaType(std::string_view headers) {
  for (std::size_t start = 0; start < headers.size();) {
    std::size_t end = headers.find("\r\n", start);
    if (end == std::string_view::npos) end = headers.size();
    const std::string_view line = headers.substr(start, end - start);
    start = end + 2;
    const std::size_t colon = line.find(':');
    if (colon == std::string_view::npos || Lower(Trim(line.substr(0, colon))) != "content-type") continue;
    return Lower(HeaderPieces(line.substr(colon + 1)).front());
  }
  return {};
}

std::vector<MultipartPart> SplitMultipart(std::string_view body, std::string_view boundary, std::size_t max_parts) {
  const std::string delimiter = "\r\n--" + std::string(boundary);
  std::vector<MultipartPart> parts;
  std::size_t position = AfterFirstDelimiter(body, boundary);
  while (body.substr(position, 2) != "--") {  // "--" after a delimiter closes the body
    if (parts.size() == max_parts) throw MultipartError(fmt::format("the body has more than {} parts", max_parts));
    position = AfterDelimiterLine(body, position);
    MultipartPart part;
    std::size_t content = position + 2;  // a part without headers starts with the blank line
    if (body.substr(position, 2) != "\r\n") {
      const std::size_t blank = body.find("\r\n\r\n", position);
      if (blank == std::string_view::npos) throw MultipartError("a part has no blank line after its headers");
      if (blank - position > kMaxPartHeaderBytes) throw MultipartError("a part's headers are longer than 16 KiB");
      part.headers = body.substr(position, blank - position);
      content = blank + 4;
    }
    const std::size_t next = body.find(delimiter, content);
    if (next == std::string_view::npos) throw MultipartError("the body is truncated: a part has no closing boundary");
    part.body = body.substr(content, next - content);
    parts.push_back(part);
    position = next + delimiter.size();
  }
  return parts;
}

std::string JoinMultipart(const std::vector<std::string>& parts, std::string_view boundary,
                          std::string_view part_type) {
  std::string body;
  std::size_t size = 0;
  for (const std::string& part : parts) size += part.size() + boundary.size() + part_type.size() + 32;
  body.reserve(size + boundary.size() + 8);
  for (const std::string& part : parts) {
    body += fmt::format("--{}\r\nContent-Type: {}\r\n\r\n", boundary, part_type);
    body += part;
    body += "\r\n";
  }
  body += fmt::format("--{}--\r\n", boundary);
  return body;
}

std::string NewBoundary() {
  std::random_device random;
  std::string boundary = "cinevol-";
  while (boundary.size() < 48) boundary += fmt::format("{:08x}", random());
  return boundary.substr(0, 48);
}

}  // namespace cinevol::pacs
