// multipart/related bodies (RFC 2046, RFC 2387) as DICOMweb uses them: WADO-RS
// answers with DICOM instances in parts, STOW-RS sends them so. Bodies from a
// PACS are hostile: every malformation is an error naming what was wrong.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace cinevol::pacs {

// A multipart body or header that is not what RFC 2046 says.
class MultipartError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct MultipartPart {
  std::string_view headers;  // the part's header lines, CRLF-separated, without the blank line
  std::string_view body;     // the part's bytes, views into the whole body
};

// The boundary of a `multipart/related` Content-Type (quoted or not); throws
// MultipartError when the type is not multipart/related or the boundary is
// absent or not a valid one (1 to 70 characters of RFC 2046's bchars).
std::string MultipartBoundary(std::string_view content_type);

// The value of the Content-Type header among `headers` (lower-cased, without
// parameters), or empty where there is none.
std::string PartMediaType(std::string_view headers);

// The parts of `body`, at most `max_parts` of them; throws MultipartError for a
// body without its first delimiter, a part without its blank line, a body cut
// before its closing delimiter, or more than `max_parts` parts.
std::vector<MultipartPart> SplitMultipart(std::string_view body, std::string_view boundary, std::size_t max_parts);

// A multipart/related body of `parts`, each with `Content-Type: part_type`.
std::string JoinMultipart(const std::vector<std::string>& parts, std::string_view boundary, std::string_view part_type);

// A boundary no DICOM instance is likely to hold: random, 48 characters.
std::string NewBoundary();

}  // namespace cinevol::pacs
