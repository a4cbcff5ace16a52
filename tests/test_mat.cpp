// MATLAB .mat import: the EMPS benchmark file against the values its README publishes, and files written here with
// libmatio itself (v5 and v7.3) read back exactly.
#include "feedid/io/mat.hpp"

#include <gtest/gtest.h>

#include <matio.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "feedid/error.hpp"
#include "feedid/io/import.hpp"
#include "testing.hpp"

using namespace feedid;
using feedid::testing::count_lines;
using feedid::testing::run_cli;
using feedid::testing::shared_data;

namespace {

bool contains(const std::string& text, std::string_view part) { return text.find(part) != std::string::npos; }

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
        add(name, MAT_C_DOUBLE, MAT_T_DOUBLE, column ? std::vector<std::size_t>{values.size(), 1}
                                                     : std::vector<std::size_t>{1, values.size()},
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
