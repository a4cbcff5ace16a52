// MATLAB .mat import: the EMPS benchmark file against the values its README publishes, and files written here with
// libmatio itself (v5 and v7.3) read back exactly.
#include "feedid/io/mat.hpp"

#include <gtest/gtest.h>

#include <matio.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/core/error.hpp"
#include "feedid/io/import.hpp"
#include "testing.hpp"

using namespace feedid;
using feedid::testing::count_lines;
using feedid::testing::run_cli;
using feedid::testing::shared_data;

namespace {

bool contains(const std::string& text, std::string_view part) {
    return text.find(part) != std::string::npos;
}

// read_mat refuses the file with an InputError whose message holds `part`.
void expect_refused(const std::filesystem::path& path, const std::string& part) {
    try {
        (void)read_mat(path);
        ADD_FAILURE() << path << ": no InputError";
    } catch (const InputError& e) {
        EXPECT_TRUE(contains(e.what(), part)) << e.what();
    }
}

// A MAT file written with libmatio's own writer: the reader is checked against the library's idea of the format.
class MatWriter {
public:
    MatWriter(const std::filesystem::path& path, mat_ft version)
        : file_(Mat_CreateVer(path.c_str(), nullptr, version)) {}
    MatWriter(const MatWriter&) = delete;
    MatWriter& operator=(const MatWriter&) = delete;
    ~MatWriter() {
        if (file_ != nullptr) Mat_Close(file_);
    }
    [[nodiscard]] bool open() const { return file_ != nullptr; }

    void add(const char* name, matio_classes class_type, matio_types data_type, std::vector<std::size_t> dims,
             void* data) {
        matvar_t* variable = Mat_VarCreate(name, class_type, data_type, static_cast<int>(dims.size()), dims.data(),
                                           data, MAT_F_DONT_COPY_DATA);
        ASSERT_NE(variable, nullptr) << name;
        EXPECT_EQ(Mat_VarWrite(file_, variable, MAT_COMPRESSION_NONE), 0) << name;
        Mat_VarFree(variable);
    }
    void add_doubles(const char* name, std::vector<double>& values, bool column = true) {
        add(name, MAT_C_DOUBLE, MAT_T_DOUBLE,
            column ? std::vector<std::size_t>{values.size(), 1} : std::vector<std::size_t>{1, values.size()},
            values.data());
    }

private:
    mat_t* file_;
};

struct Written {
    std::vector<double> t;
    std::vector<double> x;
    std::vector<double> row;
    std::vector<std::int32_t> counts;
    std::vector<float> single;
};

// Vectors (column and row), an int32 vector, a single-precision vector, double and integer scalars.
Written write_sample(const std::filesystem::path& path, mat_ft version) {
    Written w;
    for (int k = 0; k < 7; ++k) {
        w.t.push_back(k * 0.001);
        w.x.push_back(std::pow(-3.0, k) / 7.0);
        w.row.push_back(1.0 / (k + 1.0));
        w.counts.push_back(k * k - 20);
        w.single.push_back(static_cast<float>(k) * 0.1f);
    }
    w.x[3] = std::numeric_limits<double>::denorm_min();
    MatWriter file(path, version);
    EXPECT_TRUE(file.open()) << path;
    if (!file.open()) return w;
    file.add_doubles("t", w.t);
    file.add_doubles("x", w.x);
    file.add_doubles("r", w.row, false);
    file.add("counts", MAT_C_INT32, MAT_T_INT32, {w.counts.size(), 1}, w.counts.data());
    file.add("single", MAT_C_SINGLE, MAT_T_SINGLE, {1, w.single.size()}, w.single.data());
    double gtau = 35.15;
    file.add("gtau", MAT_C_DOUBLE, MAT_T_DOUBLE, {1, 1}, &gtau);
    std::int32_t axis = 3;
    file.add("axis", MAT_C_INT32, MAT_T_INT32, {1, 1}, &axis);
    return w;
}

void expect_sample_read_back(const Trace& trace, const Written& w) {
    ASSERT_EQ(trace.channels.size(), 5u);
    EXPECT_EQ(trace.find("t")->values, w.t);
    EXPECT_EQ(trace.find("x")->values, w.x);
    EXPECT_EQ(trace.find("r")->values, w.row);
    ASSERT_EQ(trace.find("counts")->values.size(), w.counts.size());
    for (std::size_t k = 0; k < w.counts.size(); ++k) {
        EXPECT_EQ(trace.find("counts")->values[k], static_cast<double>(w.counts[k]));
        EXPECT_EQ(trace.find("single")->values[k], static_cast<double>(w.single[k]));
    }
    ASSERT_EQ(trace.constants.size(), 2u);
    EXPECT_EQ(trace.constants.at("gtau"), 35.15);
    EXPECT_EQ(trace.constants.at("axis"), 3.0);
    EXPECT_EQ(trace.format, "mat");
}

}  // namespace

// The EMPS README: t [s] with 24841 samples at 1 kHz; qm, qg [m], vir [V]; gtau = 35.15, kp = 160.18, kv = 243.45.
TEST(MatEmps, InfoReportsSamplesSampleTimeChannelsAndScalars) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto path = shared_data() / "emps/DATA_EMPS.mat";
    const auto result = run_cli("info '" + path.string() + "' --json -");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const auto document = nlohmann::json::parse(result.out);
    EXPECT_EQ(document.at("format"), "mat");
    EXPECT_EQ(document.at("samples"), 24841);
    EXPECT_NEAR(document.at("sample_time_s").get<double>(), 0.001, 1e-9);
    EXPECT_NEAR(document.at("duration_s").get<double>(), 24.840, 1e-6);  // (24841 - 1) samples of 1 ms

    std::map<std::string, std::string> roles;
    for (const auto& channel : document.at("channels")) roles[channel.at("name")] = channel.at("role");
    for (const char* name : {"qm", "qg", "vir", "t"}) EXPECT_TRUE(roles.count(name)) << name;
    for (const auto& [name, role] : roles) {
        EXPECT_TRUE(name == "qm" || name == "qg" || name == "vir" || name == "t" || name == "pulses") << name;
    }
    EXPECT_EQ(roles["t"], "time");
    EXPECT_EQ(roles["qm"], "position");
    EXPECT_EQ(roles["qg"], "reference_position");

    const auto& constants = document.at("constants");
    // to the precision the README prints them
    EXPECT_NEAR(constants.at("gtau").get<double>(), 35.15, 0.005);
    EXPECT_NEAR(constants.at("kp").get<double>(), 160.18, 0.005);
    EXPECT_NEAR(constants.at("kv").get<double>(), 243.45, 0.005);
}

TEST(MatEmps, TextSummaryNamesTheSameFacts) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto result = run_cli("info '" + (shared_data() / "emps/DATA_EMPS.mat").string() + "'");
    ASSERT_EQ(result.exit_code, 0) << result.err;
    EXPECT_TRUE(contains(result.out, "samples      24841")) << result.out;
    EXPECT_TRUE(contains(result.out, "sample time  0.001 s (1000 Hz)")) << result.out;
    for (const char* word : {"qm", "qg", "vir", "gtau", "35.15", "kp", "160.18", "kv", "243.45"}) {
        EXPECT_TRUE(contains(result.out, word)) << word << " missing in\n" << result.out;
    }
}

TEST(MatEmps, ForceConstantIsUsableByName) {
    FEEDID_REQUIRE_SHARED("emps/DATA_EMPS.mat");
    const auto trace = read_trace(shared_data() / "emps/DATA_EMPS.mat");
    EXPECT_EQ(trace.samples(), 24841u);
    // t steps by 0.99998 ms and 1.00002 ms (t[1000] = 1 s, t[20000] = 20 s): on average exactly 1 ms
    EXPECT_NEAR(trace.time_base().sample_time_s, 0.001, 1e-9);
    EXPECT_FALSE(trace.time_base().jittery);
    EXPECT_NEAR(trace.constants.at("gtau"), 35.15, 0.005);
    // qm and qg are metres of load travel; the EMPS axis spans a few tenths of a metre at most
    const auto qm = trace.column(Role::position);
    const auto [low, high] = std::minmax_element(qm.begin(), qm.end());
    EXPECT_GT(*high - *low, 0.01);
    EXPECT_LT(*high - *low, 1.0);
}

TEST(Mat, Version5ReadsBackExactly) {
    const auto path = feedid::testing::temp_dir() / "v5.mat";
    const auto written = write_sample(path, MAT_FT_MAT5);
    expect_sample_read_back(read_mat(path), written);
}

TEST(Mat, Version73ReadsBackExactly) {
    const auto path = feedid::testing::temp_dir() / "v73.mat";
    {
        // libmatio writes v7.3 only when it was built with HDF5 (Debian's is)
        mat_t* probe = Mat_CreateVer(path.c_str(), nullptr, MAT_FT_MAT73);
        if (probe == nullptr) GTEST_SKIP() << "this libmatio cannot write MAT v7.3 (built without HDF5)";
        Mat_Close(probe);
        std::filesystem::remove(path);
    }
    const auto written = write_sample(path, MAT_FT_MAT73);
    EXPECT_EQ(detect_format(path), "mat");
    expect_sample_read_back(read_mat(path), written);
}

TEST(Mat, ImportedThroughTheChainWithRolesAndFindings) {
    const auto path = feedid::testing::temp_dir() / "chain.mat";
    const auto written = write_sample(path, MAT_FT_MAT5);
    const auto trace = read_trace(path);
    EXPECT_EQ(trace.find(Role::time)->name, "t");
    EXPECT_EQ(trace.find(Role::position)->name, "x");
    // a MAT file carries no units: SI is assumed for the role channels, and said
    bool said = false;
    for (const auto& finding : trace.findings) said |= contains(finding, "'x'") && contains(finding, "no unit");
    EXPECT_TRUE(said);
    EXPECT_EQ(trace.column(Role::position)[1], written.x[1]);
}

// A demanding user keeps matrices and text in the same file as the signals: those are named in findings, not
// silently dropped, and the vectors still import.
TEST(Mat, MatricesAndTextAreLeftOutWithAFinding) {
    const auto path = feedid::testing::temp_dir() / "mixed.mat";
    Written written;
    {
        MatWriter file(path, MAT_FT_MAT5);
        ASSERT_TRUE(file.open());
        written.t = {0.0, 0.5, 1.0};
        written.x = {1.0, 2.0, 3.0};
        file.add_doubles("t", written.t);
        file.add_doubles("x", written.x);
        std::vector<double> matrix(12, 1.0);
        file.add("M", MAT_C_DOUBLE, MAT_T_DOUBLE, {3, 4}, matrix.data());
        char label[] = "axis X";
        file.add("label", MAT_C_CHAR, MAT_T_UTF8, {1, 6}, label);
        file.add("nothing", MAT_C_DOUBLE, MAT_T_DOUBLE, {0, 0}, nullptr);
    }
    const auto trace = read_mat(path);
    ASSERT_EQ(trace.channels.size(), 2u);
    EXPECT_EQ(trace.find("x")->values, written.x);
    EXPECT_TRUE(trace.constants.empty());
    auto finding_about = [&](std::string_view name) {
        for (const auto& finding : trace.findings) {
            if (contains(finding, "'" + std::string(name) + "'")) return finding;
        }
        return std::string{};
    };
    EXPECT_TRUE(contains(finding_about("M"), "3x4 matrix")) << finding_about("M");
    EXPECT_TRUE(contains(finding_about("label"), "char array")) << finding_about("label");
    EXPECT_TRUE(contains(finding_about("nothing"), "empty")) << finding_about("nothing");
}

TEST(Mat, OnlyAMatrixIsAClearError) {
    const auto dir = feedid::testing::temp_dir();
    const auto path = dir / "matrix.mat";
    {
        MatWriter file(path, MAT_FT_MAT5);
        ASSERT_TRUE(file.open());
        std::vector<double> matrix(2000, 0.25);
        file.add("data", MAT_C_DOUBLE, MAT_T_DOUBLE, {1000, 2}, matrix.data());
    }
    const auto result = run_cli("info '" + path.string() + "'");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_EQ(count_lines(result.err), 1) << result.err;
    EXPECT_TRUE(contains(result.err, path.string())) << result.err;
    EXPECT_TRUE(contains(result.err, "no numeric vector")) << result.err;
    EXPECT_TRUE(contains(result.err, "'data' is a 1000x2 matrix")) << result.err;
}

TEST(Mat, ChannelsOfAnotherLengthAreLeftOutWithAFinding) {
    const auto path = feedid::testing::temp_dir() / "lengths.mat";
    {
        MatWriter file(path, MAT_FT_MAT5);
        ASSERT_TRUE(file.open());
        std::vector<double> t{0.0, 0.1, 0.2, 0.3};
        std::vector<double> short_one{1.0, 2.0};
        file.add_doubles("t", t);
        file.add_doubles("calibration", short_one);
    }
    const auto trace = read_mat(path);
    ASSERT_EQ(trace.channels.size(), 1u);
    ASSERT_EQ(trace.findings.size(), 1u);
    EXPECT_TRUE(contains(trace.findings[0], "'calibration' has 2 samples, not 4")) << trace.findings[0];
}

TEST(Mat, NotAMatFileIsOneClearMessage) {
    const auto dir = feedid::testing::temp_dir();
    // garbage behind a MAT v5 text header
    std::string text = "MATLAB 5.0 MAT-file, written by hand";
    text.resize(116, ' ');
    text += std::string(8, '\0') + "\x00\x01IM" + std::string(64, '\x7F');
    feedid::testing::write_text(dir / "bad.mat", text);
    // and a truncated copy of a valid file
    const auto good = dir / "good.mat";
    (void)write_sample(good, MAT_FT_MAT5);
    const std::string bytes = feedid::testing::read_text(good);
    feedid::testing::write_text(dir / "truncated.mat", bytes.substr(0, bytes.size() / 2));

    const std::map<std::string, std::string> problems{{"bad.mat", "not a MATLAB .mat file"},
                                                      {"truncated.mat", "truncated after variable"}};
    for (const auto& [name, problem] : problems) {
        const auto path = dir / name;
        const auto result = run_cli("info '" + path.string() + "'");
        EXPECT_EQ(result.exit_code, 2) << name << ": " << result.err;
        EXPECT_EQ(count_lines(result.err), 1) << name << ": " << result.err;
        EXPECT_TRUE(contains(result.err, path.string())) << result.err;
        EXPECT_TRUE(contains(result.err, problem)) << result.err;
    }
}

// libmatio allocates what a variable's header claims before reading its data: a damaged header claiming two billion
// elements in a file of a few hundred bytes is refused before that, naming the variable and the claim.
TEST(Mat, HeaderClaimingMoreElementsThanTheFileHoldsIsRefused) {
    const auto dir = feedid::testing::temp_dir();
    const auto good = dir / "good.mat";
    {
        MatWriter file(good, MAT_FT_MAT5);
        ASSERT_TRUE(file.open());
        std::vector<double> t{0.0, 0.1, 0.2};
        file.add_doubles("t", t);
    }
    std::string bytes = feedid::testing::read_text(good);
    // v5, uncompressed: 128-byte file header, the variable's tag (8), array flags (16), dimensions tag (8), then
    // the first dimension as int32
    constexpr std::size_t first_dimension = 128 + 8 + 16 + 8;
    ASSERT_GT(bytes.size(), first_dimension + 8);
    ASSERT_EQ(bytes.substr(first_dimension, 8), std::string("\x03\x00\x00\x00\x01\x00\x00\x00", 8));
    bytes.replace(first_dimension, 4, std::string("\xFF\xFF\xFF\x7F", 4));
    const auto damaged = dir / "damaged.mat";
    feedid::testing::write_text(damaged, bytes);
    expect_refused(damaged, "variable 't' claims to be 2147483647x1, more than the " + std::to_string(bytes.size()) +
                                "-byte file can hold");
}

// libmatio reads a variable by name: of two with the same name the second would be read as the first, and its own
// element count applied to the first one's data (a read past its end). Refused as damaged.
TEST(Mat, TwoVariablesOfOneNameAreRefused) {
    // libmatio's writer refuses a second variable of a name, so the file is two written files joined: the second's
    // variable appended after the first's (v5 variables follow the 128-byte file header one after the other)
    const auto dir = feedid::testing::temp_dir();
    std::vector<double> few{1.0, 2.0};
    std::vector<double> many(1000, 0.5);
    for (auto [name, values] : {std::pair{"few.mat", &few}, std::pair{"many.mat", &many}}) {
        MatWriter file(dir / name, MAT_FT_MAT5);
        ASSERT_TRUE(file.open());
        file.add_doubles("x", *values);
    }
    const auto path = dir / "twice.mat";
    feedid::testing::write_text(
        path, feedid::testing::read_text(dir / "few.mat") + feedid::testing::read_text(dir / "many.mat").substr(128));
    expect_refused(path, "variable 'x' appears twice");
}

// A file that is not v5 or v7.3 is taken for v4 by libmatio, which allocates the name length a v4 header states
// before reading it (1.2 GB for a 270-byte file that fuzzing found). A v4 file is read; a damaged one refused first.
TEST(Mat, Version4IsReadAndADamagedHeaderRefused) {
    const auto dir = feedid::testing::temp_dir();
    // v4, little-endian, double (type 0000): rows, columns, no imaginary part, name length with its NUL, name, data
    auto variable = [](std::uint32_t rows, std::uint32_t name_length, const std::string& name,
                       const std::vector<double>& values) {
        std::string bytes;
        for (const std::uint32_t field : {0U, rows, 1U, 0U, name_length}) {
            bytes.append(reinterpret_cast<const char*>(&field), 4);
        }
        bytes += name + '\0';
        bytes.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(double));
        return bytes;
    };
    const std::vector<double> t{0.0, 0.001, 0.002};
    const std::vector<double> x{1.5, -2.0, 0.25};
    feedid::testing::write_text(dir / "v4.mat", variable(3, 2, "t", t) + variable(3, 2, "x", x));
    const auto trace = read_mat(dir / "v4.mat");
    ASSERT_EQ(trace.channels.size(), 2U);
    EXPECT_EQ(trace.channels[1].name, "x");
    EXPECT_EQ(trace.channels[1].values, x);

    feedid::testing::write_text(dir / "damaged.mat", variable(3, 2, "t", t) + variable(3, 0x49010000, "x", x));
    expect_refused(dir / "damaged.mat", "truncated after variable 't' (a v4 variable claims a 1224802304-byte name");
}

// libmatio allocates for a cell array's claimed cells, and for the rank its dimensions element claims, while it only
// reads the variable's header (Mat_VarReadNextInfo). The headers are checked first, compressed ones inflated; the
// inputs fuzzing found (1.9 GB of dimensions in 798 bytes, a compressed one asking 6.9 GB) are kept as regressions.
TEST(Mat, HeadersClaimingMoreThanTheFileHoldsAreRefusedBeforeLibmatioAllocates) {
    const auto dir = feedid::testing::temp_dir();
    for (const auto compression : {MAT_COMPRESSION_NONE, MAT_COMPRESSION_ZLIB}) {
        SCOPED_TRACE(compression == MAT_COMPRESSION_NONE ? "uncompressed" : "compressed");
        const auto good = dir / "cells.mat";
        {
            mat_t* file = Mat_CreateVer(good.c_str(), nullptr, MAT_FT_MAT5);
            ASSERT_NE(file, nullptr);
            std::vector<double> t{0.0, 0.1, 0.2};
            std::size_t t_dims[2] = {3, 1};
            matvar_t* tv = Mat_VarCreate("t", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, t_dims, t.data(), 0);
            ASSERT_EQ(Mat_VarWrite(file, tv, MAT_COMPRESSION_NONE), 0);
            Mat_VarFree(tv);
            std::size_t cell_dims[2] = {2, 1};
            matvar_t* cells = Mat_VarCreate("c", MAT_C_CELL, MAT_T_CELL, 2, cell_dims, nullptr, 0);
            for (std::size_t k = 0; k < 2; ++k) {
                std::size_t one[2] = {1, 1};
                double value = 1.0 + static_cast<double>(k);
                Mat_VarSetCell(cells, static_cast<int>(k),
                               Mat_VarCreate(nullptr, MAT_C_DOUBLE, MAT_T_DOUBLE, 2, one, &value, 0));
            }
            ASSERT_EQ(Mat_VarWrite(file, cells, compression), 0);
            Mat_VarFree(cells);
            Mat_Close(file);
        }
        ASSERT_NO_THROW((void)read_mat(good));  // the file as written is fine: 'c' is left out with a finding

        std::string bytes = feedid::testing::read_text(good);
        if (compression == MAT_COMPRESSION_NONE) {
            // the cell array's first dimension: after the first variable, its tag (8), array flags (16), dims tag (8)
            const std::size_t first_variable_end = 128 + 8 + (bytes[132] & 0xFF) + ((bytes[133] & 0xFF) << 8);
            const std::size_t first_dimension = first_variable_end + 8 + 16 + 8;
            ASSERT_EQ(bytes.substr(first_dimension, 4), std::string("\x02\x00\x00\x00", 4));
            bytes.replace(first_dimension, 4, std::string("\x00\x00\x00\x40", 4));  // 2^30 cells
        } else {
            // inflate the compressed variable, claim 2^30 cells, and deflate it again
            const std::size_t first_variable_end = 128 + 8 + (bytes[132] & 0xFF) + ((bytes[133] & 0xFF) << 8);
            ASSERT_EQ(bytes[first_variable_end], '\x0F');
            const std::string compressed = bytes.substr(first_variable_end + 8);
            std::string inflated(4096, '\0');
            uLongf inflated_size = inflated.size();
            ASSERT_EQ(uncompress(reinterpret_cast<Bytef*>(inflated.data()), &inflated_size,
                                 reinterpret_cast<const Bytef*>(compressed.data()), compressed.size()),
                      Z_OK);
            inflated.resize(inflated_size);
            const std::size_t first_dimension = 8 + 16 + 8;
            ASSERT_EQ(inflated.substr(first_dimension, 4), std::string("\x02\x00\x00\x00", 4));
            inflated.replace(first_dimension, 4, std::string("\x00\x00\x00\x40", 4));
            std::string deflated(compressBound(inflated.size()), '\0');
            uLongf deflated_size = deflated.size();
            ASSERT_EQ(compress(reinterpret_cast<Bytef*>(deflated.data()), &deflated_size,
                               reinterpret_cast<const Bytef*>(inflated.data()), inflated.size()),
                      Z_OK);
            deflated.resize(deflated_size);
            const auto size = static_cast<std::uint32_t>(deflated.size());
            bytes = bytes.substr(0, first_variable_end) + std::string("\x0F\x00\x00\x00", 4) +
                    std::string(reinterpret_cast<const char*>(&size), 4) + deflated;
        }
        const auto damaged = dir / "damaged.mat";
        feedid::testing::write_text(damaged, bytes);
        expect_refused(damaged,
                       "damaged or truncated after variable 't' (variable 'c' claims 1073741824 cells or "
                       "fields, more than the file holds)");
    }
}

// Every v4/v5 input fuzzing found (a header on which libmatio allocated gigabytes, or parsed past where the walk does)
// is refused as damaged before libmatio allocates, with one line naming the file; the v7.3 ones (on which HDF5 leaks,
// or asks for 171 GB and, not given it, gives up) are refused too.
TEST(Mat, EveryKeptFuzzInputIsRefusedAsDamaged) {
    const auto folder = std::filesystem::path(FEEDID_TEST_SOURCE_DIR) / "fuzz" / "regressions" / "mat";
    ASSERT_TRUE(std::filesystem::exists(folder)) << folder;
    int inputs = 0;
    for (const auto& entry : std::filesystem::directory_iterator(folder)) {
        SCOPED_TRACE(entry.path().filename().string());
        try {
            (void)read_mat(entry.path());
            ADD_FAILURE() << "no InputError";
        } catch (const InputError& e) {
            const bool hdf5 = entry.path().filename().string().starts_with("v73_");
            EXPECT_TRUE(
                contains(e.what(), entry.path().string() + (hdf5 ? ": " : ": the file is damaged or truncated")))
                << e.what();
            EXPECT_EQ(count_lines(e.what()), 0) << e.what();
        }
        ++inputs;
    }
    EXPECT_GE(inputs, 10);
}
