#include "feedid/identify.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <functional>
#include <numeric>

#include <fmt/core.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <Eigen/Dense>

#include "feedid/error.hpp"
#include "feedid/least_squares.hpp"
#include "feedid/signal.hpp"
#include "feedid/version.hpp"
#include "stribeck_fit.hpp"

namespace feedid {

std::string IdentifyOptions::validate() const {
    if (const auto problem = drive.validate(); !problem.empty()) return problem;
    if (filter_order < 1 || filter_order > 12) return "--filter-order must be between 1 and 12";
    if (cutoff_hz && !(*cutoff_hz > 0.0)) return "--cutoff must be a positive frequency [Hz]";
    if (decimation < 0 || decimation > 1000) return "--decimate must be between 1 and 1000 (0 = automatic)";
    if (savitzky_golay_window != 0 && (savitzky_golay_window < 5 || savitzky_golay_window % 2 == 0)) {
        return "--sg-window must be an odd number of samples >= 5";
    }
    if (savitzky_golay_order < 2 || savitzky_golay_order > 6) return "--sg-order must be between 2 and 6";
    if (from_s && to_s && !(*to_s > *from_s)) return "--to must be later than --from";
    if (split_velocity && !(*split_velocity >= 0.0)) return "--split-velocity must be >= 0";
    if (moving_threshold && !(*moving_threshold >= 0.0)) return "--moving-threshold must be >= 0";
    if (!(rls.forgetting_factor > 0.0 && rls.forgetting_factor <= 1.0)) return "--lambda must lie in (0, 1]";
    if (!(rls.initial_covariance > 0.0)) return "--p0 must be positive";
    return {};
}

const Parameter* IdentifyResult::find(const std::string& key) const {
    for (const auto& parameter : parameters) {
        if (parameter.key == key) return &parameter;
    }
    return nullptr;
}

namespace {

using Json = nlohmann::json;

/// The minimum (with std::less) or maximum (std::greater) of x over [k - half, k + half], for every k, in O(n)
/// with a monotonic queue of indices.
template <class Compare>
std::vector<double> running_extreme(const std::vector<double>& x, std::size_t half, Compare better) {
    const std::size_t n = x.size();
    std::vector<double> out(n);
    std::deque<std::size_t> queue;
    std::size_t next = 0;  // the next index to enter the window
    for (std::size_t k = 0; k < n; ++k) {
        const std::size_t last = std::min(n - 1, k + half);
        for (; next <= last; ++next) {
            while (!queue.empty() && !better(x[queue.back()], x[next])) queue.pop_back();
            queue.push_back(next);
        }
        while (queue.front() + half < k) queue.pop_front();
        out[k] = x[queue.front()];
    }
    return out;
}

/// Fewer quasi-static samples than this below the split speed cannot determine F_B and v_s.
constexpr std::size_t kMinimumSlowSamples = 20;

// ---------------------------------------------------------------------------------------------------------------
// Names: the result document's keys and units, linear or rotary, symmetric or per direction.

enum class Quantity { mass, viscous, coulomb, breakaway, stribeck_velocity, offset };
enum class Direction { both, forward, reverse };

struct Naming {
    bool rotary{false};

    [[nodiscard]] std::string key(Quantity quantity, Direction direction = Direction::both) const {
        const std::string dir = direction == Direction::forward   ? "_forward"
                                : direction == Direction::reverse ? "_reverse"
                                                                  : "";
        switch (quantity) {
            case Quantity::mass: return rotary ? "inertia_kgm2" : "mass_kg";
            case Quantity::viscous: return "viscous" + dir + (rotary ? "_Nms_per_rad" : "_Ns_per_m");
            case Quantity::coulomb: return "coulomb" + dir + (rotary ? "_Nm" : "_N");
            case Quantity::breakaway: return "breakaway" + dir + (rotary ? "_Nm" : "_N");
            case Quantity::stribeck_velocity: return "stribeck_velocity" + dir + (rotary ? "_rad_per_s" : "_m_per_s");
            case Quantity::offset: return rotary ? "offset_Nm" : "offset_N";
        }
        return {};
    }
    [[nodiscard]] std::string unit(Quantity quantity) const {
        switch (quantity) {
            case Quantity::mass: return rotary ? "kg*m^2" : "kg";
            case Quantity::viscous: return rotary ? "N*m*s/rad" : "N*s/m";
            case Quantity::coulomb:
            case Quantity::breakaway:
            case Quantity::offset: return rotary ? "N*m" : "N";
            case Quantity::stribeck_velocity: return rotary ? "rad/s" : "m/s";
        }
        return {};
    }
    [[nodiscard]] static std::string symbol(Quantity quantity, Direction direction) {
        const std::string dir = direction == Direction::forward ? "+" : direction == Direction::reverse ? "-" : "";
        switch (quantity) {
            case Quantity::mass: return "M";
            case Quantity::viscous: return "B" + dir;
            case Quantity::coulomb: return "F_C" + dir;
            case Quantity::breakaway: return "F_B" + dir;
            case Quantity::stribeck_velocity: return "v_s" + dir;
            case Quantity::offset: return "F_0";
        }
        return {};
    }
    [[nodiscard]] std::string velocity_unit() const { return rotary ? "rad/s" : "m/s"; }
    [[nodiscard]] std::string force_unit() const { return rotary ? "N*m" : "N"; }
    [[nodiscard]] double display_velocity_scale() const { return rotary ? 1.0 : 1000.0; }  // mm/s for messages
    [[nodiscard]] std::string display_velocity_unit() const { return rotary ? "rad/s" : "mm/s"; }
};

// ---------------------------------------------------------------------------------------------------------------
// The linear model of step 1: columns and what they estimate.

struct Column {
    Quantity quantity;
    Direction direction;
};

std::vector<Column> linear_columns(bool asymmetric, bool offset) {
    std::vector<Column> columns{{Quantity::mass, Direction::both}};
    if (asymmetric) {
        columns.push_back({Quantity::viscous, Direction::forward});
        columns.push_back({Quantity::viscous, Direction::reverse});
        columns.push_back({Quantity::coulomb, Direction::forward});
        columns.push_back({Quantity::coulomb, Direction::reverse});
    } else {
        columns.push_back({Quantity::viscous, Direction::both});
        columns.push_back({Quantity::coulomb, Direction::both});
    }
    if (offset) columns.push_back({Quantity::offset, Direction::both});
    return columns;
}

// The regressor row of a sample: eq. (11) [a, v, sgn v (, 1)], or per direction
// [a, v+, v-, s+, s- (, 1)] with v+ = max(v, 0), v- = min(v, 0), s+ = [v > 0], s- = -[v < 0]
// (so that the reverse Coulomb friction comes out as a positive magnitude, as in EMPS eq. 12).
struct Signals {
    std::vector<double> time, acceleration, velocity, force;
    // regressor columns after decimation (sign columns are decimated like every other column)
    std::vector<std::vector<double>> columns;
};

double sign_of(double v) {
    return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0);
}

std::vector<double> regressor_column(const Column& column, std::span<const double> a, std::span<const double> v) {
    std::vector<double> out(v.size());
    for (std::size_t k = 0; k < v.size(); ++k) {
        switch (column.quantity) {
            case Quantity::mass: out[k] = a[k]; break;
            case Quantity::viscous:
                out[k] = column.direction == Direction::forward   ? std::max(v[k], 0.0)
                         : column.direction == Direction::reverse ? std::min(v[k], 0.0)
                                                                  : v[k];
                break;
            case Quantity::coulomb:
                out[k] = column.direction == Direction::forward   ? (v[k] > 0.0 ? 1.0 : 0.0)
                         : column.direction == Direction::reverse ? (v[k] < 0.0 ? -1.0 : 0.0)
                                                                  : sign_of(v[k]);
                break;
            default: out[k] = 1.0; break;
        }
    }
    return out;
}

double percentile(std::vector<double> values, double fraction) {
    if (values.empty()) return 0.0;
    const auto index =
        static_cast<std::size_t>(std::clamp(fraction, 0.0, 1.0) * static_cast<double>(values.size() - 1));
    std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(index), values.end());
    return values[index];
}

// Smallest step the position signal takes (its quantisation), ignoring round-off.
double position_quantum(std::span<const double> x) {
    double range = 0.0;
    if (!x.empty()) {
        const auto [low, high] = std::minmax_element(x.begin(), x.end());
        range = *high - *low;
    }
    std::vector<double> steps;
    for (std::size_t k = 1; k < x.size(); ++k) {
        const double d = std::abs(x[k] - x[k - 1]);
        if (d > 1e-12 * std::max(range, 1e-300)) steps.push_back(d);
    }
    if (steps.empty()) return 0.0;
    return percentile(std::move(steps), 0.01);
}

// ---------------------------------------------------------------------------------------------------------------
// RLS over step-1 samples in time order, with a decimated history and transient detection.

struct RlsRun {
    Eigen::VectorXd final_estimate;
    Eigen::VectorXd averaged;
    std::size_t settled_index{0};  ///< first sample of the settled part
    bool settled{false};
    bool wound_up{false};
    bool covariance_ok{true};
    std::vector<double> history_time;
    std::vector<Eigen::VectorXd> history;
};

template <int N>
RlsRun run_rls(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y, const std::vector<double>& time,
               const RlsOptions& options, const Eigen::VectorXd& tolerance) {
    Rls<N> rls(options);
    const auto n = static_cast<std::size_t>(phi.rows());
    const std::size_t stride = std::max<std::size_t>(1, n / 2000);
    RlsRun run;
    std::vector<Eigen::VectorXd> trajectory;
    trajectory.reserve(n / stride + 2);
    std::vector<std::size_t> trajectory_index;
    typename Rls<N>::Vector row;
    for (std::size_t k = 0; k < n; ++k) {
        row = phi.row(static_cast<Eigen::Index>(k)).transpose();
        rls.update(row, y(static_cast<Eigen::Index>(k)));
        if (k % stride == 0 || k + 1 == n) {
            trajectory.emplace_back(rls.estimate());
            trajectory_index.push_back(k);
        }
    }
    run.final_estimate = rls.estimate();
    run.wound_up = rls.wound_up();
    const auto& p = rls.covariance();
    run.covariance_ok = p.allFinite() && (p - p.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * p.cwiseAbs().maxCoeff();
    // Transient: the first point after which every parameter stays within its tolerance of the final estimate.
    std::size_t first_settled = trajectory.size();
    for (std::size_t i = trajectory.size(); i-- > 0;) {
        const Eigen::VectorXd deviation = (trajectory[i] - run.final_estimate).cwiseAbs();
        if ((deviation.array() <= tolerance.array()).all())
            first_settled = i;
        else
            break;
    }
    run.settled = first_settled + 1 < trajectory.size() && first_settled < trajectory.size() * 9 / 10;
    run.settled_index = first_settled < trajectory.size() ? trajectory_index[first_settled] : n;
    // The paper's value: the average of the estimate after the transient, over every sample.
    if (run.settled) {
        // re-run is avoided: average over the retained trajectory (uniformly spaced in samples)
        Eigen::VectorXd sum = Eigen::VectorXd::Zero(N);
        for (std::size_t i = first_settled; i < trajectory.size(); ++i) sum += trajectory[i];
        run.averaged = sum / static_cast<double>(trajectory.size() - first_settled);
    } else {
        run.averaged = run.final_estimate;
    }
    for (std::size_t i = 0; i < trajectory.size(); ++i) {
        run.history_time.push_back(time[trajectory_index[i]]);
        run.history.push_back(trajectory[i]);
    }
    return run;
}

RlsRun run_rls_dynamic(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y, const std::vector<double>& time,
                       const RlsOptions& options, const Eigen::VectorXd& tolerance) {
    switch (phi.cols()) {
        case 3: return run_rls<3>(phi, y, time, options, tolerance);
        case 4: return run_rls<4>(phi, y, time, options, tolerance);
        case 5: return run_rls<5>(phi, y, time, options, tolerance);
        case 6: return run_rls<6>(phi, y, time, options, tolerance);
        default: throw std::logic_error("unsupported RLS size");
    }
}

Json estimate_json(const Estimate& estimate) {
    return Json{{"value", estimate.value ? Json(*estimate.value) : Json(nullptr)},
                {"stderr", estimate.standard_error ? Json(*estimate.standard_error) : Json(nullptr)}};
}

Estimate make_estimate(double value, double standard_error) {
    Estimate e;
    if (std::isfinite(value)) e.value = value;
    if (std::isfinite(standard_error)) e.standard_error = standard_error;
    return e;
}

}  // namespace

IdentifyResult identify(const Trace& trace, const IdentifyOptions& options) {
    if (const auto problem = options.validate(); !problem.empty()) throw InputError(problem);
    const std::string source = trace.source_path.empty() ? "trace" : trace.source_path;
    const auto time_column = trace.column(Role::time);
    const auto position_column = trace.column(Role::position);
    const Channel* current = trace.find(Role::current);
    if (!trace.has(Role::force) && current != nullptr && current->unit != "N" && current->unit != "N*m" &&
        options.drive.validate().empty() && !options.drive.force_per_signal(trace)) {
        // No constant turns the drive signal into force. Whether the data can identify anything at all does not
        // depend on that scale: find out in signal units first, so that a trace that cannot identify a mass says so
        // (exit 1) instead of asking for a constant that would not help.
        IdentifyOptions signal_units = options;
        signal_units.drive = DriveConstants{};
        signal_units.drive.force_constant = 1.0;
        IdentifyResult provisional = identify(trace, signal_units);
        if (provisional.status == "failed") {
            provisional.diagnostics.push_back(
                fmt::format("{}: (figures above in units of the drive signal '{}': no force constant was given)",
                            source, current->name));
            provisional.document["diagnostics"] = provisional.diagnostics;
            return provisional;
        }
    }
    const std::vector<double> force_all = drive_force(trace, options.drive);  // throws: no force constant

    const Naming naming{trace.rotary};
    const bool asymmetric = options.model == FrictionModelKind::asymmetric;
    IdentifyResult result;
    result.model = asymmetric ? "asymmetric" : "symmetric";
    result.offset = options.offset;
    result.rotary = trace.rotary;
    result.axis.rotary = trace.rotary;
    auto& diagnostics = result.diagnostics;

    const TimeBase base = trace.samples() >= 2 ? trace.time_base() : TimeBase{};
    Json document;
    document["feedid_version"] = feedid::version;
    document["trace"] = {{"path", trace.source_path},
                         {"format", trace.format},
                         {"samples", trace.samples()},
                         {"sample_time_s", base.sample_time_s},
                         {"duration_s", base.duration_s}};
    document["model"] = result.model;
    document["rotary"] = trace.rotary;

    const auto columns = linear_columns(asymmetric, options.offset);
    // Every parameter the model reports, in document order, null until estimated.
    auto add_parameter = [&](Quantity quantity, Direction direction) {
        result.parameters.push_back(
            Parameter{naming.key(quantity, direction), Naming::symbol(quantity, direction), naming.unit(quantity), {}});
    };
    add_parameter(Quantity::mass, Direction::both);
    for (const auto direction :
         asymmetric ? std::vector{Direction::forward, Direction::reverse} : std::vector{Direction::both}) {
        add_parameter(Quantity::viscous, direction);
        add_parameter(Quantity::coulomb, direction);
    }
    if (options.offset) add_parameter(Quantity::offset, Direction::both);
    for (const auto direction :
         asymmetric ? std::vector{Direction::forward, Direction::reverse} : std::vector{Direction::both}) {
        add_parameter(Quantity::breakaway, direction);
        add_parameter(Quantity::stribeck_velocity, direction);
    }
    auto parameter = [&](Quantity quantity, Direction direction) -> Parameter& {
        const auto key = naming.key(quantity, direction);
        for (auto& p : result.parameters) {
            if (p.key == key) return p;
        }
        throw std::logic_error("unknown parameter " + key);
    };

    auto finish = [&](const std::string& status) {
        result.status = status;
        Json parameters = Json::object();
        for (const auto& p : result.parameters) parameters[p.key] = estimate_json(p.estimate);
        document["parameters"] = parameters;
        document["status"] = status;
        document["diagnostics"] = diagnostics;
        result.document = std::move(document);
        return result;
    };

    // ---- window and edge trim
    const std::size_t n_all = trace.samples();
    std::size_t first = 0, last = n_all;
    if (options.from_s)
        first = static_cast<std::size_t>(std::lower_bound(time_column.begin(), time_column.end(), *options.from_s) -
                                         time_column.begin());
    if (options.to_s)
        last = static_cast<std::size_t>(std::upper_bound(time_column.begin(), time_column.end(), *options.to_s) -
                                        time_column.begin());
    if (last <= first + 20) {
        diagnostics.push_back(
            fmt::format("{}: only {} samples in the analysis window: too short to identify anything "
                        "(record at least a few seconds of motion)",
                        source, last > first ? last - first : 0));
        return finish("failed");
    }
    const double dt = base.sample_time_s;
    const double fs = 1.0 / dt;
    std::span<const double> x(position_column.data() + first, last - first);
    {
        const auto [low, high] = std::minmax_element(x.begin(), x.end());
        if (!(*high > *low)) {
            diagnostics.push_back(
                fmt::format("{}: the position never changes in the analysis window: the axis did "
                            "not move, so nothing can be identified",
                            source));
            return finish("failed");
        }
    }

    // ---- derivatives
    const double cutoff = options.cutoff_hz.value_or(std::min(100.0, 0.1 * fs));
    std::vector<double> velocity, acceleration;
    std::string differentiation_name;
    std::size_t default_edge = 2;
    switch (options.differentiation) {
        case Differentiation::central:
            differentiation_name = "central";
            velocity = central_difference(x, dt);
            acceleration = central_difference(velocity, dt);
            break;
        case Differentiation::butterworth: {
            differentiation_name = "butterworth";
            if (!(cutoff < 0.5 * fs)) {
                throw InputError(
                    fmt::format("--cutoff {} Hz must be below half the sample rate ({} Hz)", cutoff, 0.5 * fs));
            }
            const auto filtered = filtfilt(butterworth_lowpass(options.filter_order, cutoff, fs), x);
            velocity = central_difference(filtered, dt);
            acceleration = central_difference(velocity, dt);
            // the filter's impulse response settles within ~5 periods of the cut-off
            default_edge = static_cast<std::size_t>(std::ceil(2.5 * fs / cutoff));
            break;
        }
        case Differentiation::savitzky_golay: {
            differentiation_name = "savitzky-golay";
            int window = options.savitzky_golay_window;
            if (window == 0) window = std::max(5, static_cast<int>(std::lround(0.02 * fs)) | 1);
            if (static_cast<std::size_t>(window) > x.size()) {
                diagnostics.push_back(fmt::format("{}: the trace is shorter than the Savitzky-Golay window", source));
                return finish("failed");
            }
            velocity = savitzky_golay(x, window, options.savitzky_golay_order, 1, dt);
            acceleration = savitzky_golay(x, window, options.savitzky_golay_order, 2, dt);
            default_edge = static_cast<std::size_t>(window / 2 + 1);
            break;
        }
    }
    const std::size_t edge = options.edge_samples.value_or(default_edge);
    const std::size_t n_window = x.size();
    if (n_window <= 2 * edge + 20) {
        diagnostics.push_back(
            fmt::format("{}: {} samples in the window, {} dropped at each edge: too short to identify "
                        "anything",
                        source, n_window, edge));
        return finish("failed");
    }
    const std::size_t keep_first = edge, keep_last = n_window - edge;
    const std::size_t n_kept = keep_last - keep_first;
    auto kept = [&](const std::vector<double>& column) {
        return std::vector<double>(column.begin() + static_cast<std::ptrdiff_t>(keep_first),
                                   column.begin() + static_cast<std::ptrdiff_t>(keep_last));
    };
    std::vector<double> t_kept(time_column.begin() + static_cast<std::ptrdiff_t>(first + keep_first),
                               time_column.begin() + static_cast<std::ptrdiff_t>(first + keep_last));
    std::vector<double> f_kept(force_all.begin() + static_cast<std::ptrdiff_t>(first + keep_first),
                               force_all.begin() + static_cast<std::ptrdiff_t>(first + keep_last));
    std::vector<double> v_kept = kept(velocity), a_kept = kept(acceleration);

    // ---- decimation: every regressor column and the output through the same anti-alias filter (IDIM practice)
    int decimation = options.decimation;
    if (decimation == 0) decimation = 1;
    std::vector<std::vector<double>> regressors;
    for (const auto& column : columns) regressors.push_back(regressor_column(column, a_kept, v_kept));
    std::vector<double> y = f_kept, v_dec = v_kept, a_dec = a_kept, t_dec = t_kept;
    if (decimation > 1) {
        for (auto& column : regressors) {
            if (column.size() > 0 && std::all_of(column.begin(), column.end(), [](double c) { return c == 1.0; })) {
                column.resize(decimation_indices(column.size(), decimation).size(), 1.0);
            } else {
                column = decimate(column, decimation);
            }
        }
        y = decimate(f_kept, decimation);
        v_dec = decimate(v_kept, decimation);
        a_dec = decimate(a_kept, decimation);
        std::vector<double> t;
        for (const auto k : decimation_indices(t_kept.size(), decimation)) t.push_back(t_kept[k]);
        t_dec = std::move(t);
    }
    const std::size_t n = y.size();

    // ---- data selection
    SelectionReport selection;
    selection.total = n_all;
    selection.window = n_kept;
    const double noise_v = noise_floor(v_kept);
    const double quantum = position_quantum(x);
    double max_speed = 0.0;
    for (const double v : v_dec) max_speed = std::max(max_speed, std::abs(v));
    const double threshold =
        options.moving_threshold.value_or(std::max({5.0 * noise_v, quantum * cutoff, 1e-6 * max_speed}));
    selection.moving_threshold = threshold;
    std::vector<std::size_t> moving;
    for (std::size_t k = 0; k < n; ++k) {
        if (std::abs(v_dec[k]) > threshold) moving.push_back(k);
    }
    selection.moving = moving.size();
    if (n_all > n_kept) {
        selection.notes.push_back(
            fmt::format("{} samples outside the time window or within {} samples of its edges", n_all - n_kept, edge));
    }
    if (decimation > 1) selection.notes.push_back(fmt::format("decimated by {}: {} samples remain", decimation, n));
    selection.notes.push_back(fmt::format("{} samples at rest (|v| <= {:.3g} {}, 5x the velocity noise floor {:.3g})",
                                          n - moving.size(), threshold * naming.display_velocity_scale(),
                                          naming.display_velocity_unit(), noise_v * naming.display_velocity_scale()));
    // Quasi-static samples: within 50 ms around them the velocity keeps its sign and stays within a quarter of its
    // value (constant-velocity passes; not the ramps through reversals, nor stick-slip, where the velocity drops to
    // zero and the friction is anywhere between the static limits). Step 2 and the friction curve use only these.
    const std::vector<char> steady_flags = [&] {
        const auto half = static_cast<std::size_t>(std::max(1.0, std::round(0.025 / (dt * decimation))));
        const auto low = running_extreme(v_dec, half, std::less<>{});
        const auto high = running_extreme(v_dec, half, std::greater<>{});
        std::vector<char> flags(n, 0);
        for (std::size_t k = 0; k < n; ++k) {
            flags[k] = (low[k] > 0.0 || high[k] < 0.0) && high[k] - low[k] <= 0.25 * std::abs(v_dec[k]) + 6.0 * noise_v;
        }
        return flags;
    }();
    auto steady = [&](std::size_t k) { return steady_flags[k] != 0; };
    std::vector<double> steady_speeds;
    for (const auto k : moving) {
        if (steady(k)) steady_speeds.push_back(std::abs(v_dec[k]));
    }
    const double typical_speed =
        percentile(steady_speeds.empty() ? std::vector<double>{max_speed} : steady_speeds, 0.95);
    double split = options.split_velocity.value_or(options.stribeck ? 0.1 * typical_speed : 0.0);
    split = std::max(split, threshold);
    // The regressor rows and outputs of a set of samples, for the least-squares fits below.
    auto regressor_matrix = [&](const std::vector<std::size_t>& rows) {
        Eigen::MatrixXd m(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(columns.size()));
        for (std::size_t i = 0; i < rows.size(); ++i) {
            for (std::size_t c = 0; c < columns.size(); ++c)
                m(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(c)) = regressors[c][rows[i]];
        }
        return m;
    };
    auto output_vector = [&](const std::vector<std::size_t>& rows) {
        Eigen::VectorXd out(static_cast<Eigen::Index>(rows.size()));
        for (std::size_t i = 0; i < rows.size(); ++i) out(static_cast<Eigen::Index>(i)) = y[rows[i]];
        return out;
    };
    const double base_split = split;
    if (!options.split_velocity && options.stribeck && split > threshold) {
        // Step 1 must see no Stribeck friction. Check the speeds just above the split against a fit on the faster
        // samples: while they carry more friction than their noise explains (mean residual above 3 standard errors),
        // the split doubles (at most three times, and only while the faster samples remain plenty). A mean is a
        // weak witness: a small average rise can sit on the ramp samples nearest the split, correlated with the
        // acceleration, and bias M and B far more than its size suggests.
        for (int doubling = 0; doubling < 3; ++doubling) {
            std::vector<std::size_t> band, faster;
            for (const auto k : moving) {
                const double speed = std::abs(v_dec[k]);
                if (speed >= 2.0 * split)
                    faster.push_back(k);
                else if (speed >= split)
                    band.push_back(k);
            }
            if (band.size() < kMinimumSlowSamples ||
                faster.size() < std::max<std::size_t>(20 * columns.size(), moving.size() / 5))
                break;
            const LeastSquaresResult fit = solve_least_squares(regressor_matrix(faster), output_vector(faster));
            if (fit.rank_deficient) break;
            const Eigen::VectorXd residual = output_vector(band) - regressor_matrix(band) * fit.estimate;
            double rise = 0.0;
            for (std::size_t i = 0; i < band.size(); ++i)
                rise += (v_dec[band[i]] > 0 ? 1.0 : -1.0) * residual(static_cast<Eigen::Index>(i));
            rise /= static_cast<double>(band.size());
            const double noise = 3.0 * fit.residual_std / std::sqrt(static_cast<double>(band.size()));
            if (!(rise > noise)) break;
            selection.notes.push_back(fmt::format(
                "{} samples between {:.3g} and {:.3g} {} carry {:.3g} {} more friction than the faster ones: still "
                "Stribeck, so step 1 starts at {:.3g} {}",
                band.size(), split * naming.display_velocity_scale(), 2.0 * split * naming.display_velocity_scale(),
                naming.display_velocity_unit(), rise, naming.force_unit(),
                2.0 * split * naming.display_velocity_scale(), naming.display_velocity_unit()));
            split *= 2.0;
        }
    }
    const double slow_band = split;  // the speeds below which step 2 looks for quasi-static samples
    selection.split_velocity = split;

    std::vector<std::size_t> step1, step2;
    for (const auto k : moving) {
        if (std::abs(v_dec[k]) >= split)
            step1.push_back(k);
        else if (steady(k))
            step2.push_back(k);
    }
    selection.step1 = step1.size();
    selection.step2 = step2.size();
    selection.notes.push_back(fmt::format("step 1: {} moving samples at |v| >= {:.3g} {} (Stribeck negligible)",
                                          step1.size(), split * naming.display_velocity_scale(),
                                          naming.display_velocity_unit()));
    selection.notes.push_back(fmt::format("step 2: {} quasi-static samples below {:.3g} {}", step2.size(),
                                          split * naming.display_velocity_scale(), naming.display_velocity_unit()));

    auto selection_json = [&] {
        return Json{{"total", selection.total},
                    {"window", selection.window},
                    {"moving", selection.moving},
                    {"step1", selection.step1},
                    {"step2", selection.step2},
                    {"moving_threshold", selection.moving_threshold},
                    {"split_velocity", selection.split_velocity},
                    {"notes", selection.notes}};
    };
    document["preprocessing"] = {{"differentiation", differentiation_name},
                                 {"filter_order", options.filter_order},
                                 {"cutoff_hz", cutoff},
                                 {"decimation", decimation},
                                 {"edge_samples", edge}};
    document["selection"] = selection_json();

    const std::size_t p = columns.size();
    if (step1.size() < 10 * p) {
        diagnostics.push_back(
            fmt::format("{}: only {} moving samples fast enough for step 1 (need at least {}): the "
                        "axis barely moves; record constant-velocity strokes (see feedid plan)",
                        source, step1.size(), 10 * p));
        return finish("failed");
    }

    // ---- step 1: batch least squares (the certified reference) and RLS (the paper)
    if (!options.split_velocity && step2.size() < kMinimumSlowSamples && split > threshold) {
        // Holding the slow samples back from step 1 pays only when step 2 can use them. Without quasi-static samples
        // (no slow constant-velocity passes) the slow samples are the ramps through reversals: step 1 takes them too
        // (the IDIM practice) unless they show a friction rise above the step-1 model, a Stribeck effect that would
        // bias B and F_C.
        std::vector<std::size_t> slow;
        for (const auto k : moving) {
            if (std::abs(v_dec[k]) < split) slow.push_back(k);
        }
        const LeastSquaresResult fast_fit = solve_least_squares(regressor_matrix(step1), output_vector(step1));
        if (slow.size() >= kMinimumSlowSamples && !fast_fit.rank_deficient) {
            const Eigen::VectorXd residual = output_vector(slow) - regressor_matrix(slow) * fast_fit.estimate;
            double rise = 0.0;
            for (std::size_t i = 0; i < slow.size(); ++i)
                rise += (v_dec[slow[i]] > 0 ? 1.0 : -1.0) * residual(static_cast<Eigen::Index>(i));
            rise /= static_cast<double>(slow.size());
            const bool consistent = rise <= fast_fit.residual_std;  // a Stribeck effect only ever adds friction
            selection.notes.push_back(fmt::format(
                "{} slow samples below {:.3g} {} (ramps, no quasi-static passes): friction above the fast-sample model "
                "{:.3g} {} (residual std {:.3g}): {}",
                slow.size(), split * naming.display_velocity_scale(), naming.display_velocity_unit(), rise,
                naming.force_unit(), fast_fit.residual_std,
                consistent ? "no Stribeck rise, step 1 uses them" : "a Stribeck rise, left out of step 1"));
            if (consistent) {
                step1.insert(step1.end(), slow.begin(), slow.end());
                std::sort(step1.begin(), step1.end());
                split = threshold;
                selection.split_velocity = split;
                selection.step1 = step1.size();
                selection.notes.push_back(fmt::format("step 1 now: {} moving samples at |v| >= {:.3g} {}", step1.size(),
                                                      split * naming.display_velocity_scale(),
                                                      naming.display_velocity_unit()));
            }
            document["selection"] = selection_json();
        }
    }
    const Eigen::MatrixXd phi = regressor_matrix(step1);
    const Eigen::VectorXd y1 = output_vector(step1);
    std::vector<double> t1(step1.size());
    for (std::size_t i = 0; i < step1.size(); ++i) t1[i] = t_dec[step1[i]];
    const LeastSquaresResult batch = solve_least_squares(phi, y1);
    Json batch_json = Json::object();
    for (std::size_t c = 0; c < p; ++c) {
        batch_json[naming.key(columns[c].quantity, columns[c].direction)] = estimate_json(make_estimate(
            batch.estimate(static_cast<Eigen::Index>(c)), batch.standard_error(static_cast<Eigen::Index>(c))));
    }
    document["fit"] = {{"relative_error_pct", batch.relative_error_pct},
                       {"condition_number", batch.condition_number},
                       {"samples_used", batch.samples},
                       {"residual_std", batch.residual_std},
                       {"r_diagonal", std::vector<double>(batch.r_diagonal.data(),
                                                          batch.r_diagonal.data() + batch.r_diagonal.size())}};
    document["step1"] = {{"batch", batch_json}};

    if (batch.rank_deficient) {
        // Which parameter is missing its excitation?
        std::vector<std::string> silent;
        for (std::size_t c = 0; c < p; ++c) {
            if (phi.col(static_cast<Eigen::Index>(c)).norm() == 0.0)
                silent.push_back(Naming::symbol(columns[c].quantity, columns[c].direction));
        }
        diagnostics.push_back(fmt::format(
            "{}: the step-1 regressors are linearly dependent{}: the data cannot separate "
            "the parameters (does the axis move in both directions{}?)",
            source, silent.empty() ? "" : " (no excitation of " + fmt::format("{}", fmt::join(silent, ", ")) + ")",
            options.offset ? ", and is the offset separable from Coulomb friction" : ""));
        return finish("failed");
    }

    // Mass: identifiable only when acceleration explains a significant part of the force.
    const double mass = batch.estimate(0), mass_se = batch.standard_error(0);
    if (!(mass > 0.0) || !(mass_se < 0.25 * mass)) {
        double max_acceleration = 0.0;
        for (const auto k : step1) max_acceleration = std::max(max_acceleration, std::abs(a_dec[k]));
        diagnostics.push_back(fmt::format(
            "{}: the trace carries no usable mass information: the acceleration (at most {:.3g} {}/s^2 in the samples "
            "used) explains too little of the drive force (estimate {:.4g} +/- {:.2g} {}); a micro-step or creep test "
            "cannot determine mass. Record strokes with real accelerations and reversals (see feedid plan)",
            source, max_acceleration, naming.rotary ? "rad" : "m", mass, mass_se, naming.unit(Quantity::mass)));
        parameter(Quantity::mass, Direction::both).estimate = {};
        return finish("failed");
    }
    for (std::size_t c = 0; c < p; ++c) {
        parameter(columns[c].quantity, columns[c].direction).estimate = make_estimate(
            batch.estimate(static_cast<Eigen::Index>(c)), batch.standard_error(static_cast<Eigen::Index>(c)));
    }
    auto coefficient = [&](Quantity quantity, Direction direction) {
        for (std::size_t c = 0; c < p; ++c) {
            if (columns[c].quantity == quantity && columns[c].direction == direction)
                return batch.estimate(static_cast<Eigen::Index>(c));
        }
        return 0.0;
    };

    // RLS on the same samples, in time order.
    {
        Eigen::VectorXd tolerance = (batch.estimate.cwiseAbs() * 0.02).cwiseMax(3.0 * batch.standard_error);
        const RlsRun run = run_rls_dynamic(phi, y1, t1, options.rls, tolerance);
        Json final_json = Json::object(), averaged_json = Json::object(), history = Json::object();
        history["time_s"] = run.history_time;
        for (std::size_t c = 0; c < p; ++c) {
            const auto key = naming.key(columns[c].quantity, columns[c].direction);
            final_json[key] = run.final_estimate(static_cast<Eigen::Index>(c));
            averaged_json[key] = run.averaged(static_cast<Eigen::Index>(c));
            std::vector<double> series;
            series.reserve(run.history.size());
            for (const auto& h : run.history) series.push_back(h(static_cast<Eigen::Index>(c)));
            history[key] = series;
        }
        const double transient_end =
            run.settled_index < t1.size() ? t1[run.settled_index] : (t1.empty() ? 0.0 : t1.back());
        document["rls"] = {{"variant", options.rls.variant == RlsVariant::exponential ? "exponential" : "directional"},
                           {"forgetting_factor", options.rls.forgetting_factor},
                           {"initial_covariance", options.rls.initial_covariance},
                           {"final", final_json},
                           {"averaged", averaged_json},
                           {"settled", run.settled},
                           {"transient_end_s", transient_end},
                           {"history", history}};
        if (!run.settled) {
            diagnostics.push_back(
                "RLS: the estimates did not settle within 2 % (or 3 standard errors) of their final "
                "values before the last tenth of the data; rls.averaged is the final value");
        }
        if (run.wound_up || !run.covariance_ok) {
            diagnostics.push_back(
                "RLS (the paper's exponential forgetting): the covariance wound up in directions the "
                "data does not excite; its estimates are unreliable (use the directional variant)");
        }
    }

    // ---- step 2: Stribeck, per direction
    result.axis.mass = mass;
    const double offset = options.offset ? coefficient(Quantity::offset, Direction::both) : 0.0;
    result.axis.offset = offset;
    auto linear_branch = [&](Direction direction) {
        FrictionBranch branch;
        const Direction d = asymmetric ? direction : Direction::both;
        branch.viscous = coefficient(Quantity::viscous, d);
        branch.coulomb = coefficient(Quantity::coulomb, d);
        return branch;
    };
    result.axis.friction.forward = linear_branch(Direction::forward);
    result.axis.friction.reverse = linear_branch(Direction::reverse);

    const std::array<Direction, 2> directions{Direction::forward, Direction::reverse};
    Json stribeck_json = Json::object();
    std::array<std::size_t, 2> slow_count{0, 0};
    std::array<double, 2> slow_min{INFINITY, INFINITY};
    for (const auto k : step2) {
        const int g = v_dec[k] > 0 ? 0 : 1;
        ++slow_count[static_cast<std::size_t>(g)];
        slow_min[static_cast<std::size_t>(g)] = std::min(slow_min[static_cast<std::size_t>(g)], std::abs(v_dec[k]));
    }
    const double display = naming.display_velocity_scale();
    if (options.stribeck) {
        // The paper's log-linear RLS, per direction.
        for (std::size_t g = 0; g < 2; ++g) {
            detail::FitSamples samples;
            for (const auto k : step2) {
                if ((v_dec[k] > 0) == (g == 0)) samples.push(a_dec[k], v_dec[k], y[k]);
            }
            const auto branch = g == 0 ? result.axis.friction.forward : result.axis.friction.reverse;
            const double signed_coulomb = branch.coulomb;
            const auto log_linear = detail::fit_log_linear(samples, mass, branch.viscous, signed_coulomb, offset,
                                                           2.0 * batch.residual_std, options.rls);
            stribeck_json[g == 0 ? "forward" : "reverse"]["log_linear"] = {
                {"breakaway", log_linear.breakaway ? Json(*log_linear.breakaway) : Json(nullptr)},
                {"stribeck_velocity",
                 log_linear.stribeck_velocity ? Json(*log_linear.stribeck_velocity) : Json(nullptr)},
                {"samples_used", log_linear.used},
                {"excluded_wrong_sign", log_linear.wrong_sign},
                {"excluded_below_noise", log_linear.below_noise}};
        }

        // The whole friction curve by nonlinear least squares: all step-1 samples (subsampled to a bounded count)
        // and every step-2 sample.
        detail::FitSamples samples;
        // At most about 100000 of each: beyond that the fit gains little but time (a million-sample trace).
        const std::size_t stride1 = std::max<std::size_t>(1, step1.size() / 100000);
        const std::size_t stride2 = std::max<std::size_t>(1, step2.size() / 100000);
        for (std::size_t i = 0; i < step1.size(); i += stride1)
            samples.push(a_dec[step1[i]], v_dec[step1[i]], y[step1[i]]);
        for (std::size_t i = 0; i < step2.size(); i += stride2)
            samples.push(a_dec[step2[i]], v_dec[step2[i]], y[step2[i]]);
        // and the ramp samples that only the Stribeck check kept out of step 1: the whole curve models them
        for (const auto k : moving) {
            const double speed = std::abs(v_dec[k]);
            if (speed >= base_split && speed < split && !steady(k)) samples.push(a_dec[k], v_dec[k], y[k]);
        }
        detail::CurveModel model{asymmetric, true, asymmetric, options.offset};
        constexpr std::size_t minimum_slow = kMinimumSlowSamples;
        if (asymmetric) {
            model.stribeck_forward = slow_count[0] >= minimum_slow;
            model.stribeck_reverse = slow_count[1] >= minimum_slow;
        } else {
            model.stribeck_forward = slow_count[0] + slow_count[1] >= minimum_slow;
        }
        const double slowest = std::min(slow_min[0], slow_min[1]);
        const double vs_low = std::isfinite(slowest) ? std::max(slowest / 5.0, threshold) : threshold;
        const double vs_high = std::max(split, 2.0 * vs_low);

        // Where constant-velocity passes span the fast speeds too (a designed test: the feed ladder and the slow
        // passes), the friction curve comes from the quasi-static samples alone and M from the accelerating ones with
        // that curve held: what the transients carry besides M*a (the current loop's lag, the hold of the drive
        // signal over a sample, the loop's ringing) then cannot leak into the friction parameters. A joint fit lets
        // it: on a closed-loop synthetic axis with a 0.3 ms current lag it put B 5 % high, 2 standard errors.
        // Otherwise (quasi-static samples at one speed, or none) M and the curve are fitted jointly.
        std::vector<std::size_t> quasi_static;
        for (const auto k : step1) {
            if (steady(k)) quasi_static.push_back(k);
        }
        const bool separable = [&] {
            for (std::size_t g = 0; g < (asymmetric ? 2u : 1u); ++g) {
                std::vector<double> speeds;
                for (const auto k : quasi_static) {
                    if (!asymmetric || (v_dec[k] > 0) == (g == 0)) speeds.push_back(std::abs(v_dec[k]));
                }
                // B needs quasi-static samples at speeds at least a factor two apart
                if (speeds.size() < 10 * kMinimumSlowSamples ||
                    !(percentile(speeds, 0.9) >= 2.0 * percentile(speeds, 0.1))) {
                    return false;
                }
            }
            return true;
        }();
        struct CurveResult {
            detail::CurveFit fit;
            double mass{0.0};
            double mass_se{0.0};
        };
        const auto fit_curve = [&](detail::CurveModel curve_model) {
            CurveResult out;
            if (!separable) {
                out.fit = detail::fit_friction_curve(samples, curve_model, vs_low, vs_high);
                const detail::CurveLayout layout(curve_model);
                if (out.fit.converged) {
                    out.mass = out.fit.parameters(layout.mass);
                    out.mass_se = out.fit.standard_errors(layout.mass);
                }
                return out;
            }
            curve_model.mass = false;
            const detail::CurveLayout layout(curve_model);
            out.mass = mass;
            {
                // The quasi-static samples' small accelerations take step 1's mass: one round is enough (a second,
                // with the mass of the first, moved no estimate by more than 0.001 of its standard error on 20
                // synthetic closed-loop traces).
                detail::FitSamples quasi;
                const std::size_t stride = std::max<std::size_t>(1, quasi_static.size() / 100000);
                for (std::size_t i = 0; i < quasi_static.size(); i += stride) {
                    const auto k = quasi_static[i];
                    quasi.push(0.0, v_dec[k], y[k] - out.mass * a_dec[k]);
                }
                for (std::size_t i = 0; i < step2.size(); i += stride2) {
                    const auto k = step2[i];
                    quasi.push(0.0, v_dec[k], y[k] - out.mass * a_dec[k]);
                }
                out.fit = detail::fit_friction_curve(quasi, curve_model, vs_low, vs_high);
                if (!out.fit.converged) return out;
                // M by least squares on every sample of the joint set, the friction curve held
                Eigen::VectorXd curve_parameters = out.fit.parameters;  // with ln v_s, as CurveLayout::friction takes
                for (const int index : layout.log_vs) {
                    if (index >= 0) curve_parameters(index) = std::log(curve_parameters(index));
                }
                double aa = 0.0, ar = 0.0, rr = 0.0;
                for (std::size_t k = 0; k < samples.size(); ++k) {
                    const double a = samples.acceleration[k];
                    const double r =
                        samples.force[k] - layout.friction(curve_parameters, samples.velocity[k], asymmetric);
                    aa += a * a;
                    ar += a * r;
                    rr += r * r;
                }
                if (!(aa > 0.0)) {
                    out.fit.converged = false;
                    return out;
                }
                out.mass = ar / aa;
                const double dof = static_cast<double>(samples.size()) - 1.0;
                out.mass_se = std::sqrt(std::max(0.0, rr - out.mass * ar) / std::max(dof, 1.0) / aa);
            }
            return out;
        };
        for (int attempt = 0; attempt < 3; ++attempt) {
            if (!model.stribeck_forward && !model.stribeck_reverse) break;
            const CurveResult curve = fit_curve(model);
            const detail::CurveFit& fit = curve.fit;
            const detail::CurveLayout layout([&] {
                detail::CurveModel m = model;
                m.mass = !separable;
                return m;
            }());
            bool all_ok = true;
            for (std::size_t g = 0; g < (asymmetric ? 2u : 1u); ++g) {
                bool& enabled = g == 0 ? model.stribeck_forward : model.stribeck_reverse;
                if (!enabled) continue;
                const double delta = fit.converged ? fit.parameters(layout.delta[g]) : NAN;
                const double delta_se = fit.converged ? fit.standard_errors(layout.delta[g]) : NAN;
                const double vs = fit.converged ? fit.parameters(layout.log_vs[g]) : NAN;
                const double vs_se = fit.converged ? fit.standard_errors(layout.log_vs[g]) : NAN;
                // the data determines v_s only with quasi-static samples below a few v_s
                std::size_t below = 0;
                for (const auto k : step2) {
                    if ((!asymmetric || (v_dec[k] > 0) == (g == 0)) && std::abs(v_dec[k]) < 3.0 * vs) ++below;
                }
                const bool ok = fit.converged && std::isfinite(vs) && vs > vs_low * 1.05 && vs < vs_high * 0.95 &&
                                delta > 3.0 * delta_se && vs_se < 0.3 * vs && below >= minimum_slow;
                if (!ok) {
                    enabled = false;
                    all_ok = false;
                    const std::string dir_name = asymmetric ? (g == 0 ? " (forward)" : " (reverse)") : "";
                    if (!(delta > 3.0 * delta_se) && fit.converged && std::isfinite(delta)) {
                        diagnostics.push_back(fmt::format(
                            "Stribeck{}: the slow samples show no friction rise above Coulomb friction that the noise "
                            "does not explain (F_B - F_C = {:.3g} +/- {:.2g} {}); F_B and v_s left null",
                            dir_name, delta, delta_se, naming.force_unit()));
                    } else {
                        diagnostics.push_back(fmt::format(
                            "Stribeck{}: {} quasi-static samples below 3 v_s: F_B and v_s are not determined by this "
                            "data "
                            "(fit {}); add constant-velocity passes spanning about 0.3 to 5 times the expected v_s",
                            dir_name, below,
                            fit.converged ? fmt::format("v_s = {:.3g} +/- {:.2g} {}", vs * display, vs_se * display,
                                                        naming.display_velocity_unit())
                                          : "did not converge"));
                    }
                }
            }
            if (!all_ok) continue;  // refit without the undetermined terms
            // Accept: the final parameters come from the joint nonlinear fit (no log-linear bias).
            result.axis.mass = curve.mass;
            parameter(Quantity::mass, Direction::both).estimate = make_estimate(curve.mass, curve.mass_se);
            if (options.offset) {
                result.axis.offset = fit.parameters(layout.offset);
                parameter(Quantity::offset, Direction::both).estimate =
                    make_estimate(fit.parameters(layout.offset), fit.standard_errors(layout.offset));
            }
            for (std::size_t g = 0; g < 2; ++g) {
                const std::size_t group = asymmetric ? g : 0;
                const Direction d = asymmetric ? directions[g] : Direction::both;
                FrictionBranch& branch = g == 0 ? result.axis.friction.forward : result.axis.friction.reverse;
                branch.viscous = fit.parameters(layout.viscous[group]);
                branch.coulomb = fit.parameters(layout.coulomb[group]);
                parameter(Quantity::viscous, d).estimate =
                    make_estimate(branch.viscous, fit.standard_errors(layout.viscous[group]));
                parameter(Quantity::coulomb, d).estimate =
                    make_estimate(branch.coulomb, fit.standard_errors(layout.coulomb[group]));
                if (layout.delta[group] >= 0) {
                    const double delta = fit.parameters(layout.delta[group]);
                    branch.breakaway = branch.coulomb + delta;
                    branch.stribeck_velocity = fit.parameters(layout.log_vs[group]);
                    // F_B = F_C + (F_B - F_C): var = var(F_C) + var(F_B - F_C) + 2 cov
                    const int c = layout.coulomb[group], e = layout.delta[group];
                    const double se_fb = std::sqrt(
                        std::max(0.0, fit.covariance(c, c) + fit.covariance(e, e) + 2.0 * fit.covariance(c, e)));
                    parameter(Quantity::breakaway, d).estimate = make_estimate(*branch.breakaway, se_fb);
                    parameter(Quantity::stribeck_velocity, d).estimate =
                        make_estimate(*branch.stribeck_velocity, fit.standard_errors(layout.log_vs[group]));
                }
            }
            stribeck_json["nonlinear"] = {
                {"method", separable ? "quasi-static curve, mass from the transients" : "joint"},
                {"converged", fit.converged},
                {"relative_error_pct", fit.relative_error_pct},
                {"residual_std", fit.residual_std},
                {"samples_used", fit.samples},
                {"function_evaluations", fit.iterations}};
            break;
        }
        if (!model.stribeck_forward && !model.stribeck_reverse && slow_count[0] + slow_count[1] < minimum_slow) {
            diagnostics.push_back(fmt::format(
                "Stribeck: only {} quasi-static samples below {:.3g} {} (a tenth of the typical constant-velocity "
                "speed): "
                "F_B and v_s cannot be determined; add slow constant-velocity passes (e.g. 10 to 1000 mm/min, "
                "see feedid plan)",
                slow_count[0] + slow_count[1], slow_band * display, naming.display_velocity_unit()));
        }
    } else {
        diagnostics.push_back("Stribeck step skipped (--no-stribeck): F_B and v_s not estimated");
    }
    document["stribeck"] = stribeck_json;

    // ---- per-parameter honesty: a value whose standard error exceeds its magnitude is not determined
    for (auto& p : result.parameters) {
        if (p.estimate.value && p.estimate.standard_error && p.key.rfind("offset", 0) != 0 &&
            *p.estimate.standard_error > std::abs(*p.estimate.value)) {
            diagnostics.push_back(
                fmt::format("{} = {:.4g} +/- {:.2g} {}: not determined by this data (standard error "
                            "larger than the value)",
                            p.symbol, *p.estimate.value, *p.estimate.standard_error, p.unit));
        }
    }

    // ---- the friction curve for plots: quasi-static samples, binned by speed, per direction
    {
        Json curve = Json::object();
        for (std::size_t g = 0; g < 2; ++g) {
            std::vector<std::pair<double, double>> points;  // |v|, friction magnitude
            for (const auto k : moving) {
                if (!steady(k) || (v_dec[k] > 0) != (g == 0)) continue;
                const double friction =
                    (y[k] - result.axis.mass * a_dec[k] - result.axis.offset) * (g == 0 ? 1.0 : -1.0);
                points.emplace_back(std::abs(v_dec[k]), friction);
            }
            if (points.size() < 5) continue;
            // 40 bins equally spaced in log speed, filled in one pass (no sort: a million-sample trace)
            double low = INFINITY, high = 0.0;
            for (const auto& [speed, force] : points) {
                low = std::min(low, speed);
                high = std::max(high, speed);
            }
            low = std::max(low, 1e-9);
            constexpr int bins = 40;
            const double span = std::log(std::max(high, low * (1.0 + 1e-12)) / low);
            std::array<double, bins> sum_v{}, sum_f{};
            std::array<std::size_t, bins> count{};
            for (const auto& [speed, force] : points) {
                const int b =
                    std::clamp(static_cast<int>(bins * std::log(std::max(speed, low) / low) / span), 0, bins - 1);
                sum_v[static_cast<std::size_t>(b)] += speed;
                sum_f[static_cast<std::size_t>(b)] += force;
                ++count[static_cast<std::size_t>(b)];
            }
            std::vector<double> speeds, forces, fitted;
            for (std::size_t b = 0; b < bins; ++b) {
                if (count[b] == 0) continue;
                const double speed = sum_v[b] / static_cast<double>(count[b]);
                speeds.push_back(speed);
                forces.push_back(sum_f[b] / static_cast<double>(count[b]));
                fitted.push_back(
                    (g == 0 ? result.axis.friction.forward : result.axis.friction.reverse).magnitude(speed));
            }
            const std::string velocity_key = naming.rotary ? "velocity_rad_per_s" : "velocity_m_per_s";
            const std::string force_key = naming.rotary ? "torque_Nm" : "force_N";
            curve[g == 0 ? "forward" : "reverse"] = {
                {velocity_key, speeds}, {force_key, forces}, {"fitted_" + force_key, fitted}};
        }
        document["friction_curve"] = curve;
    }

    if (!asymmetric) result.axis.friction.reverse = result.axis.friction.forward;
    bool any_null = false;
    for (const auto& p : result.parameters) any_null = any_null || !p.estimate.value;
    return finish(any_null ? "partial" : "ok");
}

}  // namespace feedid
