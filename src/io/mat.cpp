#include "feedid/io/mat.hpp"

#include <matio.h>
#include <zlib.h>

#include <fmt/core.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <fstream>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <system_error>
#include <vector>

#include "feedid/core/error.hpp"

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

// The number of elements a variable's dimensions claim; nullopt when the product overflows (a damaged header).
std::optional<std::size_t> element_count(const matvar_t& variable) {
    std::size_t elements = 1;
    for (int k = 0; k < variable.rank; ++k) {
        if (__builtin_mul_overflow(elements, variable.dims[k], &elements)) return std::nullopt;
    }
    return elements;
}

bool same_shape(const matvar_t& a, const matvar_t& b) {
    if (a.rank != b.rank || a.class_type != b.class_type) return false;
    for (int k = 0; k < a.rank; ++k) {
        if (a.dims[k] != b.dims[k]) return false;
    }
    return true;
}

// A 32-bit word of the file: stored little-endian, or big-endian when `swap` is set.
std::uint32_t word_at(const unsigned char* p, bool swap) {
    const std::uint32_t little = p[0] | (p[1] << 8) | (p[2] << 16) | (std::uint32_t{p[3]} << 24);
    return swap ? __builtin_bswap32(little) : little;
}

// libmatio sizes allocations from a v5 variable's header before checking them against the file: a dimensions
// element claiming 1.9 GB in a file of 798 bytes (found by fuzzing; the inputs are kept in tests/fuzz/regressions/mat/)
// has Mat_VarReadNextInfo allocate 3.9 GB for the rank, and a cell array or struct has it allocate a pointer for
// every element it claims, following cells within cells as deep as they go; a compressed variable does the same with
// what its inflated stream claims (6.9 GB). So the headers of the v5 variables are walked first, reading only their
// tags (a compressed variable is inflated as far as the walk goes, and never held whole), and every size or count
// libmatio would allocate for is checked against the bytes there to hold it: the file's, or at most 1032 times the
// compressed bytes (zlib's largest expansion).
class Version5HeaderCheck {
public:
    Version5HeaderCheck(const std::filesystem::path& path, std::string source, std::uintmax_t size)
        : in_(path, std::ios::binary), source_(std::move(source)), size_(size) {}

    void run() {
        std::array<unsigned char, 128> header{};
        if (!read_at(0, header.data(), header.size())) return;  // libmatio has read it; not for this check to judge
        swap_ = header[126] == 'M' && header[127] == 'I';
        std::uint64_t position = 128;
        while (position + 8 <= size_) {
            std::array<unsigned char, 8> tag{};
            if (!read_at(position, tag.data(), tag.size())) return;
            const std::uint32_t type = word(tag.data());
            const std::uint64_t bytes = word(tag.data() + 4);
            const std::uint64_t begin = position + 8;
            const std::uint64_t end = std::min<std::uint64_t>(begin + bytes, size_);
            variable_.clear();
            if (type == miMATRIX) {
                // libmatio reads a variable's header even from an element of 0 bytes, on into the next one
                if (bytes == 0) damaged("is an array element of 0 bytes");
                check_matrix(begin, end, 0);
            } else if (type == miCOMPRESSED) {
                // libmatio inflates on into the file past the element's stated size (fuzzing found an element of
                // 0 bytes whose stream, read on, claims 7 GB), so the check reads as far as it can
                inflater_.emplace(in_, begin, size_ - begin);
                std::array<unsigned char, 8> inner{};
                if (inflater_->read(0, inner.data(), inner.size()) && word(inner.data()) == miMATRIX) {
                    const std::uint64_t expanded = (size_ - begin) * 1032;
                    check_matrix(8, std::min<std::uint64_t>(8 + std::uint64_t{word(inner.data() + 4)}, expanded), 0);
                }
                inflater_.reset();
            }
            if (!variable_.empty()) previous_ = variable_;
            position = begin + bytes;
        }
    }

private:
    static constexpr std::uint32_t miINT8 = 1, miINT32 = 5, miUINT32 = 6, miMATRIX = 14, miCOMPRESSED = 15;
    static constexpr int deepest = 64;

    // A compressed variable's zlib stream, inflated forward only as far as it is read; what lies before the last
    // read is dropped, so memory stays at a window however large the variable.
    class Inflater {
    public:
        Inflater(std::ifstream& in, std::uint64_t begin, std::uint64_t bytes)
            : in_(in), next_input_(begin), input_left_(bytes) {
            ok_ = inflateInit(&stream_) == Z_OK;
        }
        Inflater(const Inflater&) = delete;
        Inflater& operator=(const Inflater&) = delete;
        ~Inflater() {
            if (ok_) inflateEnd(&stream_);
        }
        bool read(std::uint64_t offset, void* out, std::size_t count) {
            if (!ok_ || offset < window_start_) return false;
            while (true) {
                const std::uint64_t drop = std::min<std::uint64_t>(offset - window_start_, window_.size());
                window_.erase(0, drop);
                window_start_ += drop;
                if (window_start_ == offset && window_.size() >= count) break;
                if (!more()) return false;
            }
            std::copy_n(window_.data(), count, static_cast<char*>(out));
            return true;
        }

    private:
        bool more() {
            while (!finished_) {
                if (stream_.avail_in == 0) {
                    const auto chunk =
                        static_cast<std::streamsize>(std::min<std::uint64_t>(input_.size(), input_left_));
                    in_.clear();
                    in_.seekg(static_cast<std::streamoff>(next_input_));
                    if (chunk == 0 || !in_.read(input_.data(), chunk)) {
                        finished_ = true;
                        break;
                    }
                    next_input_ += static_cast<std::uint64_t>(chunk);
                    input_left_ -= static_cast<std::uint64_t>(chunk);
                    stream_.next_in = reinterpret_cast<Bytef*>(input_.data());
                    stream_.avail_in = static_cast<uInt>(chunk);
                }
                stream_.next_out = reinterpret_cast<Bytef*>(output_.data());
                stream_.avail_out = static_cast<uInt>(output_.size());
                const int code = inflate(&stream_, Z_NO_FLUSH);
                const std::size_t produced = output_.size() - stream_.avail_out;
                window_.append(output_.data(), produced);
                if (code != Z_OK) finished_ = true;  // the end of the stream, or a damaged one
                if (produced > 0) return true;
            }
            return false;
        }

        std::ifstream& in_;
        z_stream stream_{};
        bool ok_{false};
        bool finished_{false};
        std::uint64_t next_input_;
        std::uint64_t input_left_;
        std::array<char, 16384> input_{};
        std::array<char, 65536> output_{};
        std::string window_;
        std::uint64_t window_start_{0};
    };

    struct Element {
        std::uint32_t type;
        std::uint64_t data;   // where its data begins
        std::uint64_t bytes;  // how many bytes of data
        std::uint64_t next;   // where the element after it begins
    };

    bool read_at(std::uint64_t offset, void* out, std::size_t count) {
        if (inflater_) return inflater_->read(offset, out, count);
        in_.clear();
        in_.seekg(static_cast<std::streamoff>(offset));
        in_.read(static_cast<char*>(out), static_cast<std::streamsize>(count));
        return static_cast<std::size_t>(in_.gcount()) == count;
    }
    [[nodiscard]] std::uint32_t word(const unsigned char* p) const { return word_at(p, swap_); }
    [[noreturn]] void damaged(std::string_view problem) const {
        throw InputError(fmt::format(
            "{}: the file is damaged or truncated after variable '{}' ({} {})", source_, previous_,
            variable_.empty() ? std::string("the next variable") : "variable '" + variable_ + "'", problem));
    }
    [[noreturn]] void claims_too_much(std::string_view what) const {
        damaged(fmt::format("claims {}, more than the file holds", what));
    }

    // The sub-element at `position` inside [.., end): a tag of 8 bytes, or 4 bytes of tag and 4 of data (the small
    // format); data padded to 8 bytes. Of the type the format prescribes: libmatio reads what it finds otherwise in
    // ways that need not match this walk.
    Element element(std::uint64_t position, std::uint64_t end, std::string_view what, std::uint32_t type) {
        std::array<unsigned char, 8> tag{};
        if (position + 8 > end || !read_at(position, tag.data(), tag.size())) claims_too_much(what);
        const std::uint32_t first = word(tag.data());
        Element found{};
        if ((first >> 16) != 0) {
            if ((first >> 16) > 4)
                claims_too_much(fmt::format("{} of {} bytes in a 4-byte element", what, first >> 16));
            found = {first & 0xFFFF, position + 4, first >> 16, position + 8};
        } else {
            const std::uint64_t bytes = word(tag.data() + 4);
            if (bytes > end - position - 8) claims_too_much(fmt::format("{} of {} bytes", what, bytes));
            found = {first, position + 8, bytes, position + 8 + (bytes + 7) / 8 * 8};
        }
        if (found.type != type) damaged(fmt::format("has {} of data type {}, not {}", what, found.type, type));
        return found;
    }

    std::uint64_t product(const std::vector<std::uint32_t>& counts) const {
        std::uint64_t total = 1;
        for (const auto count : counts) {
            if (__builtin_mul_overflow(total, std::uint64_t{count}, &total)) return UINT64_MAX;
        }
        return total;
    }

    std::vector<std::uint32_t> words(const Element& e) {
        if (e.bytes > 4 * 1024) claims_too_much(fmt::format("{} dimensions", e.bytes / 4));
        std::vector<std::uint32_t> out(e.bytes / 4);
        std::vector<unsigned char> raw(out.size() * 4);
        if (!raw.empty() && !read_at(e.data, raw.data(), raw.size())) claims_too_much("a dimension past the end");
        for (std::size_t k = 0; k < out.size(); ++k) out[k] = word(raw.data() + 4 * k);
        return out;
    }

    // One miMATRIX element's content [begin, end): array flags, dimensions, name, then what its class holds.
    void check_matrix(std::uint64_t begin, std::uint64_t end, int depth) {
        if (begin >= end) return;  // an empty element
        if (depth > deepest) damaged(fmt::format("holds cells or structs nested deeper than {}", deepest));
        const auto flags = element(begin, end, "array flags", miUINT32);
        std::array<unsigned char, 4> flag_word{};
        if (flags.bytes < 4 || !read_at(flags.data, flag_word.data(), 4)) claims_too_much("array flags");
        const auto class_type = word(flag_word.data()) & 0xFF;
        const auto dimensions = element(flags.next, end, "dimensions", miINT32);
        // libmatio reads bytes / 4 dimensions and goes on from there, not from the padded end
        if (dimensions.bytes % 4 != 0)
            damaged(fmt::format("has dimensions of {} bytes, not whole int32", dimensions.bytes));
        const auto elements = product(words(dimensions));
        const auto name = element(dimensions.next, end, "a name", miINT8);
        if (depth == 0) {
            std::string text(std::min<std::uint64_t>(name.bytes, 63), '\0');
            if (read_at(name.data, text.data(), text.size())) variable_ = text;
        }
        std::uint64_t position = name.next;
        std::uint64_t fields = 1;
        if (class_type == MAT_C_OBJECT) position = element(position, end, "a class name", miINT8).next;
        if (class_type == MAT_C_STRUCT || class_type == MAT_C_OBJECT) {
            const auto length_element = element(position, end, "a field name length", miINT32);
            const auto length = words(length_element);
            const auto names = element(length_element.next, end, "field names", miINT8);
            const std::uint64_t length_of_name = length.empty() ? 0 : length.front();
            if (length_of_name == 0 && names.bytes > 0) damaged("has field names of length 0");
            fields = length_of_name == 0 ? 0 : names.bytes / length_of_name;
            position = names.next;
        } else if (class_type != MAT_C_CELL && class_type != MAT_C_FUNCTION) {
            return;  // numbers, text, sparse: libmatio allocates for their data only when asked to read it
        }
        // every cell (a function handle holds its parts as cells), and every field of every struct element, is a
        // miMATRIX element of at least its 8-byte tag
        std::uint64_t children = UINT64_MAX;
        if (!__builtin_mul_overflow(elements, fields, &children) && children <= (end - position) / 8) {
            for (std::uint64_t k = 0; k < children; ++k) {
                const auto child = element(position, end, "a cell or field", miMATRIX);
                check_matrix(child.data, child.data + child.bytes, depth + 1);
                position = child.data + child.bytes;
            }
            return;
        }
        claims_too_much(fmt::format("{} cells or fields",
                                    children == UINT64_MAX ? std::string("2^64 or more") : std::to_string(children)));
    }

    std::ifstream in_;
    std::string source_;
    std::uintmax_t size_;
    bool swap_{false};
    std::string variable_;
    std::string previous_{"(none)"};
    std::optional<Inflater> inflater_;
};

// A v4 file has no file header: Mat_Open takes a file that is not v5 or v7.3 for v4 and reads its first variable's
// header, allocating the name length it finds there (fuzzing found 1.2 GB asked for by a 270-byte file). So before
// libmatio opens such a file, the v4 variable headers are walked and each name and data size checked against the
// bytes that follow (v4 has no compression). A file whose first bytes are no v4 header is left to libmatio to refuse.
void check_version4_headers(const std::filesystem::path& path, const std::string& source, std::uintmax_t size) {
    std::ifstream in(path, std::ios::binary);
    std::array<unsigned char, 128> header{};
    in.read(reinterpret_cast<char*>(header.data()), header.size());
    if (static_cast<std::size_t>(in.gcount()) == header.size()) {
        const bool little = header[126] == 'I' && header[127] == 'M';
        const bool big = header[126] == 'M' && header[127] == 'I';
        // the version word, 0x0100 (v5) or 0x0200 (v7.3), in the byte order the endian indicator states
        const int version = little && header[124] == 0 ? header[125] : big && header[125] == 0 ? header[124] : 0;
        if (version == 1 || version == 2) return;
    }
    std::uint64_t position = 0;
    std::string previous = "(none)";
    while (position + 20 <= size) {
        std::array<unsigned char, 20> raw{};
        in.clear();
        in.seekg(static_cast<std::streamoff>(position));
        if (!in.read(reinterpret_cast<char*>(raw.data()), raw.size())) return;
        // The type (MOPT digits, at most 4052) is read as libmatio reads it: swapped when it is no type as it
        // stands. The other four words are in the byte order its M digit states (0 little-endian, 1 big-endian),
        // whichever order the type word itself was in: fuzzing found a type word in big-endian order with M = 0,
        // whose name length libmatio then read little-endian as 1.3 GB.
        std::uint32_t type = word_at(raw.data(), false);
        if (type > 4052) type = __builtin_bswap32(type);
        const bool v4 = type <= 1052 && (type / 100) % 10 == 0 && (type / 10) % 10 <= 5 && type % 10 <= 2;
        if (!v4) return;  // no v4 header (or VAX, Cray): libmatio stops or refuses here too
        const bool swap = type / 1000 == 1;
        std::array<std::uint32_t, 5> fields{type};  // type, rows, columns, imaginary part, name length
        for (std::size_t k = 1; k < fields.size(); ++k) fields[k] = word_at(raw.data() + 4 * k, swap);
        constexpr std::array<std::uint64_t, 6> element_bytes{8, 4, 4, 2, 2, 1};
        const std::uint64_t rest = size - position - 20;
        std::uint64_t data = 0;
        const bool overflow =
            __builtin_mul_overflow(std::uint64_t{fields[1]}, std::uint64_t{fields[2]}, &data) ||
            __builtin_mul_overflow(data, element_bytes[(type / 10) % 10] * (fields[3] != 0 ? 2 : 1), &data);
        if (fields[4] > rest || overflow || data > rest - fields[4]) {
            throw InputError(
                fmt::format("{}: the file is damaged or truncated after variable '{}' (a v4 variable "
                            "claims a {}-byte name and {}x{} values, more than the file holds)",
                            source, previous, fields[4], fields[1], fields[2]));
        }
        std::string name(std::min<std::uint32_t>(fields[4], 63), '\0');
        in.read(name.data(), static_cast<std::streamsize>(name.size()));
        previous = name.c_str();
        position += 20 + fields[4] + data;
    }
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

using MatFile = std::unique_ptr<mat_t, MatCloser>;
using MatVariable = std::unique_ptr<matvar_t, VarFreer>;

// A file open in libmatio, with what the size checks of its variables go by.
struct OpenMatFile {
    std::string source;
    std::uintmax_t bytes{0};
    MatFile file;
    bool hdf5{false};  // v7.3
};

// Opens the file in libmatio once its variable headers are known not to make libmatio allocate more than the file
// holds (check_version4_headers, Version5HeaderCheck).
OpenMatFile open_checked(const std::filesystem::path& path) {
    OpenMatFile mat;
    mat.source = path.string();
    install_matio_log();
    last_matio_message().clear();
    std::error_code size_error;
    mat.bytes = std::filesystem::file_size(path, size_error);
    if (size_error) throw InputError(fmt::format("{}: cannot read the file ({})", mat.source, size_error.message()));
    check_version4_headers(path, mat.source, mat.bytes);
    mat.file.reset(Mat_Open(mat.source.c_str(), MAT_ACC_RDONLY));
    if (!mat.file) throw InputError(fmt::format("{}: not a MATLAB .mat file libmatio can read", mat.source));
    mat.hdf5 = Mat_GetVersion(mat.file.get()) == MAT_FT_MAT73;
    if (Mat_GetVersion(mat.file.get()) == MAT_FT_MAT5) Version5HeaderCheck(path, mat.source, mat.bytes).run();
    return mat;
}

// The next variable's header, or nullptr after the last.
MatVariable next_variable_info(const OpenMatFile& mat, const std::string& previous) {
    last_matio_message().clear();
    MatVariable info(Mat_VarReadNextInfo(mat.file.get()));
    // the end of the variables, or a file cut short: libmatio tells them apart only by its log
    if (!info && !last_matio_message().empty()) {
        throw InputError(fmt::format("{}: the file is damaged or truncated after variable '{}' ({})", mat.source,
                                     previous, last_matio_message()));
    }
    return info;
}

std::optional<std::string> not_real_numeric(const matvar_t& info, const std::string& name) {
    const bool numeric = info.class_type >= MAT_C_DOUBLE && info.class_type <= MAT_C_UINT64;
    if (numeric && !info.isComplex) return std::nullopt;
    const std::string_view what = info.isComplex ? "complex array" : class_name(info.class_type);
    return fmt::format("variable '{}' is a {} {}, not a real numeric vector or scalar: left out", name,
                       dimensions(info), what);
}

// The elements a variable's header claims. libmatio allocates what a variable's header claims before it reads a byte
// of the data, so a damaged header claiming billions of elements would have it allocate gigabytes. No variable holds
// more elements than its file has room for: an element takes at least one byte (MATLAB stores small integers as
// int8), and zlib (v5 compressed variables, the deflate filter of v7.3's HDF5) expands at most 1032-fold.
std::size_t claimed_elements(const OpenMatFile& mat, const matvar_t& info, const std::string& name) {
    const auto counted = element_count(info);
    const std::uintmax_t expansion = mat.hdf5 || info.compression == MAT_COMPRESSION_ZLIB ? 1032 : 1;
    if (!counted || *counted / expansion > mat.bytes) {
        throw InputError(
            fmt::format("{}: variable '{}' claims to be {}, more than the {}-byte file can hold (the "
                        "file is damaged)",
                        mat.source, name, dimensions(info), mat.bytes));
    }
    return *counted;
}

std::optional<std::string> not_a_vector(const matvar_t& info, const std::string& name, std::size_t elements) {
    std::size_t longest_dimension = 0;
    for (int k = 0; k < info.rank; ++k) longest_dimension = std::max(longest_dimension, info.dims[k]);
    if (elements == 0) return fmt::format("variable '{}' is empty ({}): left out", name, dimensions(info));
    if (elements != longest_dimension) {
        return fmt::format(
            "variable '{}' is a {} matrix, not a vector: left out (save each signal "
            "as a vector of its own)",
            name, dimensions(info));
    }
    return std::nullopt;
}

// The variable's data. What was read must be what the header announced, and hold data for every element.
MatVariable read_data(const OpenMatFile& mat, const matvar_t& info, const std::string& name, std::size_t elements) {
    last_matio_message().clear();
    MatVariable variable(Mat_VarRead(mat.file.get(), name.c_str()));
    if (!variable || variable->data == nullptr) {
        throw InputError(fmt::format(
            "{}: variable '{}' cannot be read{}", mat.source, name,
            last_matio_message().empty() ? std::string(" (a truncated file?)") : " (" + last_matio_message() + ")"));
    }
    if (!same_shape(info, *variable) || variable->isComplex ||
        variable->nbytes / std::max<std::size_t>(Mat_SizeOf(variable->data_type), 1) < elements) {
        throw InputError(
            fmt::format("{}: variable '{}' reads back other than its header says (the file is "
                        "damaged)",
                        mat.source, name));
    }
    return variable;
}

// A real numeric vector becomes a channel and a scalar a constant; anything else is left out, and the reason
// returned.
std::optional<std::string> take_variable(const OpenMatFile& mat, const matvar_t& info, const std::string& name,
                                         Trace& trace) {
    if (auto why = not_real_numeric(info, name)) return why;
    const std::size_t elements = claimed_elements(mat, info, name);
    if (auto why = not_a_vector(info, name, elements)) return why;
    const MatVariable variable = read_data(mat, info, name, elements);
    std::vector<double> values;
    if (!to_doubles(*variable, elements, values)) {
        return fmt::format("variable '{}' holds a number type feedid does not read: left out", name);
    }
    if (values.size() == 1) {
        trace.constants[name] = values.front();
    } else {
        trace.channels.push_back(Channel{name, Role::other, "", "", std::move(values)});
    }
    return std::nullopt;
}

// Channels of a different length than the longest cannot share its time base: keep them apart as findings.
void keep_longest_channels(Trace& trace) {
    std::size_t longest = 0;
    for (const auto& channel : trace.channels) longest = std::max(longest, channel.values.size());
    std::erase_if(trace.channels, [&](const Channel& channel) {
        if (channel.values.size() == longest) return false;
        trace.findings.push_back(fmt::format("variable '{}' has {} samples, not {}: left out", channel.name,
                                             channel.values.size(), longest));
        return true;
    });
}

}  // namespace

Trace read_mat(const std::filesystem::path& path) {
    const OpenMatFile mat = open_checked(path);
    Trace trace;
    trace.source_path = mat.source;
    trace.format = "mat";
    // Variables that cannot be a channel or a constant are left out and each is named in a finding: a cell, struct
    // or char array, a complex value, or a matrix (which column would be which signal is not for import to guess).
    std::vector<std::string> left_out;
    std::set<std::string> seen;
    std::string previous = "(none)";
    while (const MatVariable info = next_variable_info(mat, previous)) {
        if (info->name == nullptr) continue;
        const std::string name = info->name;
        previous = name;
        // libmatio reads a variable by name, so of two with one name the second could not be read as itself.
        if (!seen.insert(name).second) {
            throw InputError(fmt::format("{}: variable '{}' appears twice (the file is damaged)", mat.source, name));
        }
        if (auto why = take_variable(mat, *info, name, trace)) left_out.push_back(std::move(*why));
    }
    if (trace.channels.empty()) {
        std::string held;
        for (const auto& finding : left_out) held += "; " + finding;
        throw InputError(
            fmt::format("{}: the .mat file holds no numeric vector to use as a channel{}", mat.source, held));
    }
    keep_longest_channels(trace);
    trace.findings.insert(trace.findings.end(), left_out.begin(), left_out.end());
    return trace;
}

}  // namespace feedid
