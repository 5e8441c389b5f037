#include "core/error.hpp"

namespace voxtier {

namespace {
std::string oneLine(std::string s) {
    for (char& c : s)
        if (c == '\n' || c == '\r') c = ' ';
    return s;
}
std::string format(const std::string& file, const std::string& field, const std::string& reason) {
    std::string msg = file.empty() ? std::string("<input>") : file;
    if (!field.empty()) msg += ": " + field;
    msg += ": " + reason;
    return oneLine(msg);
}
} // namespace

InputError::InputError(std::string file, std::string field, std::string reason)
    : std::runtime_error(format(file, field, reason)), file_(std::move(file)),
      field_(std::move(field)), reason_(std::move(reason)) {}

} // namespace voxtier
