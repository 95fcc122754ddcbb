// libjpeg reports errors through a callback that must not return: a jump
// back to the caller's setjmp, with the message kept. For this folder's
// sources that call libjpeg (image_codecs.cpp, jpeg_tables.cpp).
#pragma once

#include <jpeglib.h>

#include <csetjmp>

namespace cinevol {

struct JpegError {
  jpeg_error_mgr mgr;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

inline void OnJpegError(j_common_ptr cinfo) {
  auto* err = reinterpret_cast<JpegError*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, err->message);
  std::longjmp(err->jump, 1);
}

}  // namespace cinevol
