#include "feedid/io/mat.hpp"

#include <matio.h>

#include <fmt/core.h>

#include <memory>

#include "feedid/error.hpp"

namespace feedid {

namespace {
struct MatCloser {
    void operator()(mat_t* file) const { Mat_Close(file); }
};
struct VarFreer {
    void operator()(matvar_t* variable) const { Mat_VarFree(variable); }
};

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
    std::unique_ptr<mat_t, MatCloser> file(Mat_Open(source.c_str(), MAT_ACC_RDONLY));
    if (!file) throw InputError(fmt::format("{}: not a MATLAB .mat file libmatio can read", source));

    Trace trace;
    trace.source_path = source;
    trace.format = "mat";
    std::vector<std::string> skipped;
    while (true) {
        std::unique_ptr<matvar_t, VarFreer> info(Mat_VarReadNextInfo(file.get()));
        if (!info) break;
        if (info->name == nullptr) continue;
        const std::string name = info->name;
        if (info->rank != 2 || info->isComplex || info->class_type == MAT_C_CELL || info->class_type == MAT_C_STRUCT ||
            info->class_type == MAT_C_CHAR || info->class_type == MAT_C_SPARSE || info->class_type == MAT_C_OBJECT ||
            info->class_type == MAT_C_FUNCTION || info->class_type == MAT_C_EMPTY) {
            skipped.push_back(name);
            continue;
        }
        const std::size_t rows = info->dims[0];
        const std::size_t cols = info->dims[1];
        if (rows == 0 || cols == 0) continue;
        const bool vector = rows == 1 || cols == 1;
        if (!vector) {
            skipped.push_back(name);
            continue;
        }
        std::unique_ptr<matvar_t, VarFreer> variable(Mat_VarRead(file.get(), name.c_str()));
        if (!variable) throw InputError(fmt::format("{}: variable '{}' cannot be read (truncated file?)", source, name));
        std::vector<double> values;
        if (!to_doubles(*variable, rows * cols, values)) {
            skipped.push_back(name);
            continue;
        }
        if (values.size() == 1) {
            trace.constants[name] = values.front();
        } else {
            trace.channels.push_back(Channel{name, Role::other, "", "", std::move(values)});
        }
    }
    if (trace.channels.empty()) {
        throw InputError(fmt::format("{}: the .mat file holds no numeric vector to use as a channel", source));
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
    for (const auto& name : skipped) {
        trace.findings.push_back(fmt::format("variable '{}' is not a numeric vector or scalar: left out", name));
    }
    return trace;
}

}  // namespace feedid
