#include "feedid/core/null_reasons.hpp"

#include <cmath>
#include <map>

#include <fmt/core.h>

namespace feedid {

namespace {

void collect(nlohmann::json& node, const std::string& path, std::vector<std::string>& paths) {
    if (node.is_number_float() && !std::isfinite(node.get<double>())) node = nullptr;
    if (node.is_null()) {
        paths.push_back(path);
    } else if (node.is_object()) {
        for (auto& [key, child] : node.items()) collect(child, path.empty() ? key : path + "." + key, paths);
    } else if (node.is_array()) {
        for (std::size_t i = 0; i < node.size(); ++i) collect(node[i], fmt::format("{}[{}]", path, i), paths);
    }
}

// "series.time_s[3]" -> "series.time_s[]"; a path outside arrays is kept.
std::string without_indices(const std::string& path) {
    std::string out;
    bool inside = false;
    for (const char c : path) {
        if (c == '[') {
            inside = true;
            out += "[]";
        } else if (c == ']') {
            inside = false;
        } else if (!inside) {
            out += c;
        }
    }
    return out;
}

// The size of the array a path "a.b[]" names in `document` (0 when there is none).
std::size_t array_size(const nlohmann::json& document, const std::string& path) {
    const nlohmann::json* node = &document;
    std::size_t start = 0;
    const std::string plain = path.substr(0, path.find('['));
    while (start <= plain.size()) {
        const auto dot = plain.find('.', start);
        const std::string key = plain.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
        if (!node->is_object() || !node->contains(key)) return 0;
        node = &(*node)[key];
        if (dot == std::string::npos) break;
        start = dot + 1;
    }
    return node->is_array() ? node->size() : 0;
}

}  // namespace

std::vector<std::string> null_paths(nlohmann::json& document) {
    std::vector<std::string> paths;
    collect(document, "", paths);
    return paths;
}

void explain_nulls(nlohmann::json& document, const NullReason& reason_of) {
    // the nulls of each reason, in document order; an array's nulls once, with their count
    std::vector<std::string> reasons;
    std::map<std::string, std::vector<std::string>> named;
    std::map<std::string, std::size_t> array_nulls;
    for (const auto& path : null_paths(document)) {
        if (path.rfind("diagnostics", 0) == 0) continue;
        std::string reason = reason_of(path);
        if (reason.empty()) reason = "not a finite number";
        const std::string name = without_indices(path);
        if (name != path && array_nulls[name]++ > 0) continue;
        if (!named.contains(reason)) reasons.push_back(reason);
        named[reason].push_back(name);
    }
    if (reasons.empty()) return;
    if (!document.contains("diagnostics") || !document["diagnostics"].is_array())
        document["diagnostics"] = nlohmann::json::array();
    for (const auto& reason : reasons) {
        std::string names;
        for (const auto& name : named[reason]) {
            names += names.empty() ? "" : ", ";
            names += name;
            if (const auto found = array_nulls.find(name); found != array_nulls.end()) {
                names += fmt::format(" ({} of {} values)", found->second, array_size(document, name));
            }
        }
        document["diagnostics"].push_back(fmt::format("{}: null, {}", names, reason));
    }
}

}  // namespace feedid
