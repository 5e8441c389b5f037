#include "core/error.hpp"

#include <cmath>

namespace voxtier {

namespace {
std::string oneLine(std::string s) {
    for (char& c : s)
        if (c == '\n' || c == '\r') c = ' ';
    return s;
}
std::string format(const std::string& file, const std::string& field, const std::string& reason) {
    // "file: field: reason"; parts that are empty (a CLI argument has no file) are left out.
    std::string msg = file;
    for (const std::string* part : {&field, &reason}) {
        if (part->empty()) continue;
        if (!msg.empty()) msg += ": ";
        msg += *part;
    }
    return oneLine(msg);
}
} // namespace

InputError::InputError(std::string file, std::string field, std::string reason)
    : std::runtime_error(format(file, field, reason)), file_(std::move(file)),
      field_(std::move(field)), reason_(std::move(reason)) {}

double Limits::checkedSigma(double sigma, const std::string& file, const std::string& field) {
    if (!std::isfinite(sigma) || !(sigma > 0.0) || sigma > kMaxSigma)
        throw InputError(file, field,
                         "expected virtual pixels per voxel in (0, " +
                             std::to_string(int(kMaxSigma)) + "], got " + std::to_string(sigma));
    return sigma;
}

} // namespace voxtier
