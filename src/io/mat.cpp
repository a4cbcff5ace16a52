#include "feedid/io/mat.hpp"

#include <matio.h>

#include <fmt/core.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "feedid/error.hpp"

namespace feedid {

namespace {
struct MatCloser {
    void operator()(mat_t* file) const { Mat_Close(file); }
};
struct VarFreer {
    void operator()(matvar_t* variable) const { Mat_VarFree(variable); }
};

// libmatio reports problems through a log function that by default prints to stderr; feedid says what went wrong
// itself, in one sentence, so the library's own lines are kept (the last one) for that sentence instead.
std::string& last_matio_message() {
    thread_local std::string message;
    return message;
}
void keep_matio_message(int /*log_level*/, char* message) {
    if (message != nullptr) last_matio_message() = message;
}
void install_matio_log() {
    static const bool installed = [] {
        Mat_LogInitFunc("feedid", keep_matio_message);
        return true;
    }();
    (void)installed;
}

std::string_view class_name(matio_classes class_type) {
    switch (class_type) {
        case MAT_C_CELL: return "cell array";
        case MAT_C_STRUCT: return "struct";
        case MAT_C_OBJECT: return "object";
        case MAT_C_CHAR: return "char array";
        case MAT_C_SPARSE: return "sparse matrix";
        case MAT_C_FUNCTION: return "function handle";
        case MAT_C_OPAQUE: return "opaque object";
        case MAT_C_EMPTY: return "empty value";
        default: return "numeric array";
    }
}

std::string dimensions(const matvar_t& variable) {
    std::string text;
    for (int k = 0; k < variable.rank; ++k) text += (k > 0 ? "x" : "") + std::to_string(variable.dims[k]);
    return text;
}

template <typename T>
void append_as_double(const void* data, std::size_t count, std::vector<double>& out) {
    const auto* typed = static_cast<const T*>(data);
    out.reserve(count);
    for (std::size_t k = 0; k < count; ++k) out.push_back(static_cast<double>(typed[k]));
}

bool to_doubles(const matvar_t& variable, std::size_t count, std::vector<double>& out) {
    if (variable.data == nullptr || variable.isComplex) return false;
    switch (variable.data_type) {
        case MAT_T_DOUBLE: append_as_double<double>(variable.data, count, out); return true;
        case MAT_T_SINGLE: append_as_double<float>(variable.data, count, out); return true;
        case MAT_T_INT8: append_as_double<std::int8_t>(variable.data, count, out); return true;
        case MAT_T_UINT8: append_as_double<std::uint8_t>(variable.data, count, out); return true;
        case MAT_T_INT16: append_as_double<std::int16_t>(variable.data, count, out); return true;
        case MAT_T_UINT16: append_as_double<std::uint16_t>(variable.data, count, out); return true;
        case MAT_T_INT32: append_as_double<std::int32_t>(variable.data, count, out); return true;
        case MAT_T_UINT32: append_as_double<std::uint32_t>(variable.data, count, out); return true;
        case MAT_T_INT64: append_as_double<std::int64_t>(variable.data, count, out); return true;
        case MAT_T_UINT64: append_as_double<std::uint64_t>(variable.data, count, out); return true;
        default: return false;
    }
}
}  // namespace

Trace read_mat(const std::filesystem::path& path) {
    const std::string source = path.string();
    install_matio_log();
    last_matio_message().clear();
    std::unique_ptr<mat_t, MatCloser> file(Mat_Open(source.c_str(), MAT_ACC_RDONLY));
    if (!file) throw InputError(fmt::format("{}: not a MATLAB .mat file libmatio can read", source));

    Trace trace;
    trace.source_path = source;
    trace.format = "mat";
    // Variables that cannot be a channel or a constant are left out and each is named in a finding: a cell, struct
    // or char array, a complex value, or a matrix (which column would be which signal is not for import to guess).
    std::vector<std::string> left_out;
    std::string previous = "(none)";
    while (true) {
        last_matio_message().clear();
        std::unique_ptr<matvar_t, VarFreer> info(Mat_VarReadNextInfo(file.get()));
        if (!info) {
            // the end of the variables, or a file cut short: libmatio tells them apart only by its log
            if (!last_matio_message().empty()) {
                throw InputError(fmt::format("{}: the file is damaged or truncated after variable '{}' ({})", source,
                                             previous, last_matio_message()));
            }
            break;
        }
        if (info->name == nullptr) continue;
        const std::string name = info->name;
        previous = name;
        const bool numeric = info->class_type >= MAT_C_DOUBLE && info->class_type <= MAT_C_UINT64;
        if (!numeric || info->isComplex) {
            const std::string_view what = info->isComplex ? "complex array" : class_name(info->class_type);
            left_out.push_back(fmt::format("variable '{}' is a {} {}, not a real numeric vector or scalar: left out",
                                           name, dimensions(*info), what));
            continue;
        }
        std::size_t elements = 1;
        std::size_t longest_dimension = 0;
        for (int k = 0; k < info->rank; ++k) {
            elements *= info->dims[k];
            longest_dimension = std::max(longest_dimension, info->dims[k]);
        }
        if (elements == 0) {
            left_out.push_back(fmt::format("variable '{}' is empty ({}): left out", name, dimensions(*info)));
            continue;
        }
        if (elements != longest_dimension) {
            left_out.push_back(fmt::format("variable '{}' is a {} matrix, not a vector: left out (save each signal "
                                           "as a vector of its own)",
                                           name, dimensions(*info)));
            continue;
        }
        last_matio_message().clear();
        std::unique_ptr<matvar_t, VarFreer> variable(Mat_VarRead(file.get(), name.c_str()));
        if (!variable || variable->data == nullptr) {
            throw InputError(fmt::format("{}: variable '{}' cannot be read{}", source, name,
                                         last_matio_message().empty() ? std::string(" (a truncated file?)")
                                                                      : " (" + last_matio_message() + ")"));
        }
        std::vector<double> values;
        if (!to_doubles(*variable, elements, values)) {
            left_out.push_back(fmt::format("variable '{}' holds a number type feedid does not read: left out", name));
            continue;
        }
        if (values.size() == 1) {
            trace.constants[name] = values.front();
        } else {
            trace.channels.push_back(Channel{name, Role::other, "", "", std::move(values)});
        }
    }
    if (trace.channels.empty()) {
        std::string held;
        for (const auto& finding : left_out) held += "; " + finding;
        throw InputError(fmt::format("{}: the .mat file holds no numeric vector to use as a channel{}", source, held));
    }
    // Channels of a different length than the longest cannot share its time base: keep them apart as findings.
    std::size_t longest = 0;
    for (const auto& channel : trace.channels) longest = std::max(longest, channel.values.size());
    std::erase_if(trace.channels, [&](const Channel& channel) {
        if (channel.values.size() == longest) return false;
        trace.findings.push_back(fmt::format("variable '{}' has {} samples, not {}: left out", channel.name,
                                             channel.values.size(), longest));
        return true;
    });
    trace.findings.insert(trace.findings.end(), left_out.begin(), left_out.end());
    return trace;
}

}  // namespace feedid
