// The message of the `Error` that `call` throws, or "(no error)": for tests
// that check what an error says (other exceptions pass through).
#pragma once

#include <string>

namespace cinevol::testing {

template <class Error, class Call>
std::string ErrorOf(Call&& call) {
  try {
    call();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace cinevol::testing
