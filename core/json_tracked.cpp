#include "core/detail/json_tracked.hpp"

#include "core/detail/json_fields.hpp"
#include "core/error.hpp"

#include <algorithm>
#include <set>
#include <utility>
#include <vector>

namespace voxtier::detail {

namespace {

struct PathFrame {
    bool isArray = false;
    std::size_t index = 0;
    bool hasKey = false;
    std::string key;
    std::set<std::string> seen;
};

std::string trackedPath(const std::vector<PathFrame>& stack) {
    std::string p;
    for (const auto& f : stack) {
        if (f.isArray)
            p = element(p, f.index);
        else if (f.hasKey)
            p = child(p, f.key);
    }
    return p;
}

std::pair<int, int> lineColumn(const std::string& text, std::size_t byte) {
    // nlohmann's byte is 1-based: the offending character is text[byte - 1].
    const std::size_t end = std::min(text.size(), byte > 0 ? byte - 1 : 0);
    int line = 1, column = 1;
    for (std::size_t i = 0; i < end; ++i) {
        if (text[i] == '\n')
            ++line, column = 1;
        else
            ++column;
    }
    return {line, column};
}

/// nlohmann's what() minus its "[json.exception.xxx.nnn] " prefix.
std::string jsonDetail(const json::exception& e) {
    std::string s = e.what();
    if (!s.empty() && s[0] == '[') {
        const auto close = s.find("] ");
        if (close != std::string::npos) s = s.substr(close + 2);
    }
    // Drop nlohmann's own position prefix: we print ours, computed the same way every time.
    const auto colon = s.find(": ");
    if (s.rfind("parse error", 0) == 0 && colon != std::string::npos) s = s.substr(colon + 2);
    return s;
}

} // namespace

json parseTracked(const std::string& text, const std::string& file) {
    std::vector<PathFrame> stack;
    auto advance = [&] {
        if (stack.empty()) return;
        if (stack.back().isArray)
            ++stack.back().index;
        else
            stack.back().hasKey = false;
    };
    const json::parser_callback_t cb = [&](int, json::parse_event_t ev, json& parsed) {
        switch (ev) {
        case json::parse_event_t::object_start:
            stack.push_back({});
            break;
        case json::parse_event_t::array_start:
            stack.push_back({true});
            break;
        case json::parse_event_t::key: {
            PathFrame& f = stack.back();
            f.key = parsed.get<std::string>();
            f.hasKey = true;
            // nlohmann keeps the last of duplicate keys; a duplicate is almost always an
            // editing mistake, so say so instead of silently dropping the first value.
            if (!f.seen.insert(f.key).second)
                throw InputError(file, trackedPath(stack), "duplicate key '" + f.key + "'");
            break;
        }
        case json::parse_event_t::object_end:
        case json::parse_event_t::array_end:
            stack.pop_back();
            advance();
            break;
        case json::parse_event_t::value:
            advance();
            break;
        }
        return true;
    };
    try {
        return json::parse(text, cb, /*allow_exceptions=*/true, /*ignore_comments=*/false);
    } catch (const json::parse_error& e) {
        const auto [line, column] = lineColumn(text, e.byte);
        throw InputError(file, trackedPath(stack),
                         "invalid JSON at line " + std::to_string(line) + ", column " +
                             std::to_string(column) + ": " + jsonDetail(e));
    } catch (const json::out_of_range& e) {
        // 406: a number literal that does not fit a double (1e999): not a finite number.
        throw InputError(file, trackedPath(stack),
                         "expected a finite number (" + jsonDetail(e) + ")");
    } catch (const json::exception& e) {
        throw InputError(file, trackedPath(stack), "invalid JSON: " + jsonDetail(e));
    }
}

} // namespace voxtier::detail
