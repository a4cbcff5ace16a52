// Issue 15's acceptance: feedid scan on the three example part programs (pocket, contour, drilling), axes X and Y,
// 10 seeds each, cutting forces on. M within 3 %, B within 10 %, F_C within 3 % of the truth the trace's header
// states; the scatter over the seeds against the mean reported standard error within 0.7-1.5; F_B and v_s within 4
// of their standard errors of the truth or null with a reason; the same scans with --no-robust visibly biased.
// One test per program (ctest runs them in parallel); each prints the table of what it measured.
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "testing.hpp"

namespace feedid {
namespace {

constexpr int seeds = 10;

struct Parameter {
    const char* key;    ///< the document's parameter key
    const char* truth;  ///< the trace header's constant, after "<axis>_"
    double tolerance;   ///< relative, of the truth; 0: judged by its standard error
};

const std::vector<Parameter> step1 = {{"mass_kg", "true_mass_kg", 0.03},
                                      {"viscous_Ns_per_m", "true_viscous_forward_Ns_per_m", 0.10},
                                      {"coulomb_N", "true_coulomb_forward_N", 0.03}};
const std::vector<Parameter> stribeck = {{"breakaway_N", "true_breakaway_forward_N", 0.0},
                                         {"stribeck_velocity_m_per_s", "true_stribeck_velocity_forward_m_per_s", 0.0}};

struct Run {
    nlohmann::json robust, plain;
    std::map<std::string, double> constants;
};

// The "# NAME = VALUE" lines at the head of a synth CSV file (the truth of each axis).
std::map<std::string, double> header_constants(const std::filesystem::path& path) {
    std::map<std::string, double> constants;
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line) && line.rfind('#', 0) == 0) {
        const auto equal = line.find(" = ");
        if (equal == std::string::npos) continue;
        try {
            constants[line.substr(2, equal - 2)] = std::stod(line.substr(equal + 3));
        } catch (const std::exception&) {}
    }
    return constants;
}

std::vector<Run> scan_program(const std::string& program, const std::string& axis) {
    const auto dir = testing::suite_dir("scan_programs");
    std::vector<Run> runs;
    for (int seed = 1; seed <= seeds; ++seed) {
        const auto trace = dir / fmt::format("{}_{}.csv", program, seed);
        if (!std::filesystem::exists(trace)) {
            const auto source = std::filesystem::path(FEEDID_TEST_SOURCE_DIR) / ".." / "examples" / "programs";
            const auto r = testing::run_cli(fmt::format("synth --program '{}' --seed {} --out '{}'",
                                                        (source / (program + ".ngc")).string(), seed, trace.string()));
            EXPECT_EQ(r.exit_code, 0) << r.err;
        }
        Run run;
        const std::string common = fmt::format(
            "scan '{}' --axis {} --force-constant {}_force_constant_N_per_A --json -", trace.string(), axis, axis);
        for (auto [document, extra] : {std::pair{&run.robust, ""}, std::pair{&run.plain, " --no-robust"}}) {
            const auto r = testing::run_cli(common + extra);
            EXPECT_LE(r.exit_code, 1) << r.err;
            *document = nlohmann::json::parse(r.out);
        }
        run.constants = header_constants(trace);
        runs.push_back(std::move(run));
    }
    return runs;
}

double truth_of(const Run& run, const std::string& axis, const Parameter& p) {
    return run.constants.at(axis + "_" + p.truth);
}

bool has_reason(const nlohmann::json& d) {
    return d.contains("diagnostics") && !d["diagnostics"].empty();
}

struct Summary {
    std::size_t determined{0};
    double mean{0.0}, scatter{0.0}, mean_se{0.0}, worst{0.0};
};

Summary summarize(const std::vector<Run>& runs, const std::string& axis, const Parameter& p, bool robust) {
    Summary s;
    std::vector<double> values;
    for (const auto& run : runs) {
        const auto& q = (robust ? run.robust : run.plain)["parameters"][p.key];
        if (q["value"].is_null()) continue;
        const double v = q["value"].get<double>();
        values.push_back(v);
        if (!q["stderr"].is_null()) s.mean_se += q["stderr"].get<double>();
        s.worst = std::max(s.worst, std::abs(v / truth_of(run, axis, p) - 1.0));
    }
    s.determined = values.size();
    if (values.empty()) return s;
    for (const double v : values) s.mean += v / static_cast<double>(values.size());
    for (const double v : values) s.scatter += (v - s.mean) * (v - s.mean);
    s.scatter = values.size() > 1 ? std::sqrt(s.scatter / static_cast<double>(values.size() - 1)) : 0.0;
    s.mean_se /= static_cast<double>(values.size());
    return s;
}

// What one program's scans of one axis showed, for the axis's pooled figures.
struct AxisResult {
    double plain_miss{0.0};             ///< --no-robust: the largest |mean / truth - 1| over M, B, F_C, in tolerances
    double windows{0.0};                ///< mean qualified windows over the seeds
    std::array<double, 3> ratio_sum{};  ///< (seeds - 1) (scatter / mean standard error)^2 per parameter
    std::array<int, 3> degrees{};       ///< seeds - 1 where determined in every seed
};

// Programs with fewer qualified windows than this on an axis have their scatter ratio pooled with the axis's other
// programs (a ratio of 10 seeds scatters by about 25 % on its own; with few windows the cluster covariance is
// noisier still).
constexpr double few_windows = 20.0;

// Checks one axis of one program: M, B, F_C within tolerance in every seed (or null with a reason), F_B and v_s within
// 4 standard errors (or null with a reason); the scatter ratio on its own when the program has many windows.
AxisResult check_axis(const std::string& program, const std::string& axis) {
    const std::vector<Run> runs = scan_program(program, axis);
    EXPECT_EQ(runs.size(), static_cast<std::size_t>(seeds));
    AxisResult result;
    for (const auto& run : runs) result.windows += run.robust["windows"]["qualified"].get<double>() / seeds;
    fmt::print("{} {}: windows qualified (mean over seeds) {:.1f} of {}\n", program, axis, result.windows,
               runs[0].robust["windows"]["total"].get<int>());
    fmt::print("  {:<28} {:>5} {:>12} {:>12} {:>9} {:>9} {:>7} {:>10}\n", "parameter", "n", "truth", "mean", "worst %",
               "scatter", "ratio", "no-robust");
    for (std::size_t i = 0; i < step1.size(); ++i) {
        const Parameter& p = step1[i];
        const Summary s = summarize(runs, axis, p, true);
        const Summary plain = summarize(runs, axis, p, false);
        const double truth = truth_of(runs[0], axis, p);
        const double ratio = s.scatter / s.mean_se;
        const std::string plain_bias =
            plain.determined > 0 ? fmt::format("{:+.2f}%", 100.0 * (plain.mean / truth - 1.0)) : "null";
        fmt::print("  {:<28} {:>5} {:>12.5g} {:>12.5g} {:>9.2f} {:>9.3g} {:>7.2f} {:>10}\n", p.key, s.determined, truth,
                   s.mean, 100.0 * s.worst, s.scatter, ratio, plain_bias);
        if (plain.determined > 0)
            result.plain_miss = std::max(result.plain_miss, std::abs(plain.mean / truth - 1.0) / p.tolerance);
        if (s.determined < static_cast<std::size_t>(seeds)) {
            // an axis the program barely moves: null with a reason in every seed where not determined
            for (const auto& run : runs) {
                if (run.robust["parameters"][p.key]["value"].is_null()) {
                    EXPECT_TRUE(has_reason(run.robust));
                }
            }
            continue;
        }
        EXPECT_LE(s.worst, p.tolerance) << program << " " << axis << " " << p.key;
        if (result.windows >= few_windows) {
            EXPECT_GE(ratio, 0.7) << program << " " << axis << " " << p.key;
            EXPECT_LE(ratio, 1.5) << program << " " << axis << " " << p.key;
        } else {
            result.ratio_sum[i] = (seeds - 1) * ratio * ratio;
            result.degrees[i] = seeds - 1;
        }
    }
    for (const auto& p : stribeck) {
        int reported = 0;
        for (const auto& run : runs) {
            const auto& q = run.robust["parameters"][p.key];
            if (q["value"].is_null()) {
                EXPECT_TRUE(has_reason(run.robust)) << program << " " << axis << " " << p.key;
                continue;
            }
            ++reported;
            if (q["stderr"].is_null()) {
                ADD_FAILURE() << program << " " << axis << " " << p.key << ": a value without a standard error";
                continue;
            }
            const double truth = truth_of(run, axis, p);
            EXPECT_LE(std::abs(q["value"].get<double>() - truth), 4.0 * q["stderr"].get<double>())
                << program << " " << axis << " " << p.key << " " << q.dump();
        }
        fmt::print("  {:<28} reported in {} of {} seeds\n", p.key, reported, seeds);
    }
    return result;
}

// One axis over the three programs. The scatter ratios of the programs with few windows pooled: the root of the
// variance ratios weighted by their degrees of freedom. Without robust weighting the cutting forces enter the pool:
// on at least one program one of M, B, F_C (the mean over the seeds) misses the truth by more than its acceptance
// tolerance, on the traces the robust scan passes on (drilling cuts along Z: its X and Y see no cutting force).
void check_axis_over_programs(const std::string& axis) {
    std::array<double, 3> sum{};
    std::array<int, 3> degrees{};
    double plain_miss = 0.0;
    for (const char* program : {"pocket", "contour", "drilling"}) {
        const AxisResult r = check_axis(program, axis);
        plain_miss = std::max(plain_miss, r.plain_miss);
        for (std::size_t i = 0; i < 3; ++i) {
            sum[i] += r.ratio_sum[i];
            degrees[i] += r.degrees[i];
        }
    }
    for (std::size_t i = 0; i < 3; ++i) {
        if (degrees[i] == 0) continue;
        const double pooled = std::sqrt(sum[i] / degrees[i]);
        fmt::print(
            "axis {} {}: scatter / standard error pooled over the programs with few windows: {:.2f} ({} "
            "degrees of freedom)\n",
            axis, step1[i].key, pooled, degrees[i]);
        EXPECT_GE(pooled, 0.7) << axis << " " << step1[i].key;
        EXPECT_LE(pooled, 1.5) << axis << " " << step1[i].key;
    }
    fmt::print("axis {}: --no-robust misses by up to {:.2f} of the tolerance\n", axis, plain_miss);
    EXPECT_GT(plain_miss, 1.0) << axis << ": without robust weighting the scans are not visibly biased";
}

TEST(ScanPrograms, AxisX) {
    check_axis_over_programs("X");
}

TEST(ScanPrograms, AxisY) {
    check_axis_over_programs("Y");
}

}  // namespace
}  // namespace feedid
