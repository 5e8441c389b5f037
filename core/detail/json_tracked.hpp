#pragma once
// Internal to core's scene loader (not installed): JSON text -> json, with the path of the value
// being parsed tracked, so that the errors the parser raises (syntax, number overflow such as
// 1e999, duplicate keys) name a JSON path too.
#include <nlohmann/json.hpp>

#include <string>

namespace voxtier::detail {

/// The parsed document, or InputError(file, path, reason): "invalid JSON at line L, column C:
/// ...", "duplicate key 'k'" or "expected a finite number (...)".
nlohmann::json parseTracked(const std::string& text, const std::string& file);

} // namespace voxtier::detail
