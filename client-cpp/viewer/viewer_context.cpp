// The lines a script run prints.
#include "viewer/viewer_context.h"

#include <google/protobuf/util/json_util.h>

#include <cstdio>

namespace cinevol::viewer {

google::protobuf::Value TextValue(const std::string& text) {
  google::protobuf::Value v;
  v.set_string_value(text);
  return v;
}

google::protobuf::Value NumberValue(double number) {
  google::protobuf::Value v;
  v.set_number_value(number);
  return v;
}

void ScriptLog::Report(const std::string& action, const google::protobuf::Struct& fields) const {
  if (!scripted_) return;  // a person's clicks print nothing
  std::string json;
  google::protobuf::util::MessageToJsonString(fields, &json);
  std::printf("cinevol-viewer: %s %s\n", action.c_str(), json.c_str());
  std::fflush(stdout);
}

}  // namespace cinevol::viewer
