// What cinevol's DCMTK writers (a measurement report, a presentation state) share: checked study attributes, the
// date and time, and a data set encoded as a Part 10 file.
#pragma once

#include <dcmtk/config/osconfig.h>  // first, as DCMTK asks
#include <dcmtk/dcmdata/dcfilefo.h>

#include <functional>
#include <string>
#include <string_view>

#include "pacs/secondary_capture.h"

namespace cinevol::pacs {

// InputError "<field> <why>".
[[noreturn]] void Refuse(std::string_view field, std::string_view why);

// std::runtime_error "<document>: <what>: <DCMTK's text>" when `condition` is bad: DCMTK refusing what cinevol
// made is cinevol's bug, not the caller's.
void Require(const OFCondition& condition, std::string_view document, std::string_view what);

// DCMTK's messages go to its own logger; a server keeps only its errors.
void QuietDcmtk();

// DICOM pads values with spaces; a value from a PACS may keep them.
std::string WithoutTrailingSpaces(std::string text);
bool IsAscii(std::string_view text);

// A study attribute set through DCMTK, which checks it against its VR and VM, and at most `max_characters` long
// (for a PN, each of its groups): refused naming `field`, never cut (a changed copy would no longer match the study).
void SetChecked(const std::string& field, const std::string& value, std::size_t max_characters, bool person_name,
                const std::function<OFCondition(const OFString&, OFBool)>& set);

struct DicomNow {
  std::string date;  // DA, local time
  std::string time;  // TM, HHMMSS
};
DicomNow CurrentDateTime();

// Text from outside (a study's attributes, a description) put into `item`, where DCMTK checks it against its VR,
// at most `max_characters` long: refused naming `field`, never cut.
void PutText(DcmItem& item, const DcmTagKey& tag, const std::string& field, const std::string& value,
             std::size_t max_characters, bool person_name = false);

// The patient and study attributes of `study` copied into `item` (PutText: "source.<field>" names a refused one).
void PutStudyAttributes(DcmItem& item, const SourceStudy& study);

// `file` as Part 10 bytes in `syntax` (explicit VR little endian, or one whose pixel data the file already holds
// encapsulated), with new file meta information.
std::string ToPart10(DcmFileFormat& file, std::string_view document, E_TransferSyntax syntax = EXS_LittleEndianExplicit);

}  // namespace cinevol::pacs
