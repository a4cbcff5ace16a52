#include "feedid/identify/friction_map.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/core/json_adapters.hpp"
#include "feedid/core/parameters.hpp"
#include "feedid/identify/result_document.hpp"
#include "feedid/core/version.hpp"

namespace feedid {

namespace {

std::span<const double> stroke_signal(const Trace& trace) {
    // The reference is noise-free and holds still in the dwells; the measured position serves when it is absent.
    if (trace.has(Role::reference_position)) return trace.column(Role::reference_position);
    if (trace.has(Role::position)) return trace.column(Role::position);
    throw InputError(fmt::format("{}: the friction map needs a position or reference position channel.",
                                 trace.source_path.empty() ? std::string("trace") : trace.source_path));
}

double median(std::vector<double> values) {
    if (values.empty()) return std::nan("");
    const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
    std::nth_element(values.begin(), middle, values.end());
    if (values.size() % 2 == 1) return *middle;
    const double upper = *middle;
    const double lower = *std::max_element(values.begin(), middle);
    return 0.5 * (lower + upper);
}

// Indices of the turning points of x: a maximum (minimum) is confirmed once x has come back from it by more than
// the hysteresis, so measurement noise smaller than that makes no turning points.
std::vector<std::size_t> turning_points(std::span<const double> x, double hysteresis) {
    std::vector<std::size_t> turns;
    if (x.empty()) return turns;
    turns.push_back(0);
    int direction = 0;
    std::size_t high = 0;
    std::size_t low = 0;
    std::size_t extreme = 0;
    for (std::size_t k = 1; k < x.size(); ++k) {
        if (direction == 0) {
            if (x[k] > x[high]) high = k;
            if (x[k] < x[low]) low = k;
            if (x[k] - x[low] > hysteresis) {
                if (low != 0) turns.push_back(low);
                direction = 1;
                extreme = k;
            } else if (x[high] - x[k] > hysteresis) {
                if (high != 0) turns.push_back(high);
                direction = -1;
                extreme = k;
            }
        } else if (direction > 0) {
            if (x[k] >= x[extreme]) {
                extreme = k;
            } else if (x[extreme] - x[k] > hysteresis) {
                turns.push_back(extreme);
                direction = -1;
                extreme = k;
            }
        } else {
            if (x[k] <= x[extreme]) {
                extreme = k;
            } else if (x[k] - x[extreme] > hysteresis) {
                turns.push_back(extreme);
                direction = 1;
                extreme = k;
            }
        }
    }
    if (direction != 0 && turns.back() != extreme) turns.push_back(extreme);
    return turns;
}

/// A position along the axis as messages show it: "12.500 mm", rotary "90.000 deg".
std::string position_text(double position, const FrictionMap& map) {
    const ParameterNaming naming{map.rotary};
    return fmt::format("{:.3f} {}", position * naming.display_position_scale(), naming.display_position_unit());
}

nlohmann::json finite_or_null(double value) {
    return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json();
}

}  // namespace

std::string FrictionMapOptions::validate() const {
    if (auto problem = identify.validate(); !problem.empty()) return problem;
    for (const double c : centers) {
        if (!std::isfinite(c)) return "a centre is not a finite number";
    }
    if (!(turning_hysteresis > 0.0)) return "the turning-point hysteresis must be positive";
    if (!(center_tolerance > 0.0)) return "the centre tolerance must be positive";
    if (min_strokes < 1) return "a centre needs at least one stroke";
    if (!(deviation_threshold > 0.0)) return "the deviation threshold must be positive";
    return {};
}

std::vector<double> detect_centers(const Trace& trace, const FrictionMapOptions& options) {
    const auto x = stroke_signal(trace);
    const auto turns = turning_points(x, options.turning_hysteresis);
    // Midpoints of the strokes between consecutive turning points; strokes about one centre share their midpoint.
    std::vector<double> midpoints;
    for (std::size_t k = 0; k + 1 < turns.size(); ++k) {
        const double a = x[turns[k]];
        const double b = x[turns[k + 1]];
        if (std::abs(b - a) < 4.0 * options.turning_hysteresis) continue;
        midpoints.push_back(0.5 * (a + b));
    }
    std::sort(midpoints.begin(), midpoints.end());
    std::vector<double> centers;
    std::size_t start = 0;
    for (std::size_t k = 1; k <= midpoints.size(); ++k) {
        if (k < midpoints.size() && midpoints[k] - midpoints[k - 1] <= options.center_tolerance) continue;
        if (static_cast<int>(k - start) >= options.min_strokes) {
            centers.push_back(median(std::vector<double>(midpoints.begin() + static_cast<std::ptrdiff_t>(start),
                                                         midpoints.begin() + static_cast<std::ptrdiff_t>(k))));
        }
        start = k;
    }
    return centers;
}

namespace {

struct Span {
    int center;
    std::size_t first;
    std::size_t last;  ///< one past
};

/// The centres to cut at: as given, or found from the strokes (sorted).
std::vector<double> map_centers(const Trace& trace, const FrictionMapOptions& options, const std::string& where,
                                FrictionMap& map) {
    std::vector<double> centers = options.centers;
    if (centers.empty()) {
        centers = detect_centers(trace, options);
        map.centers_detected = true;
        if (centers.empty()) {
            throw InputError(
                fmt::format("{}: no centre found about which the axis strokes back and forth at least {} "
                            "times; give the centres with --centers.",
                            where, options.min_strokes));
        }
    }
    std::sort(centers.begin(), centers.end());
    return centers;
}

/// Each sample to its nearest centre; segments in time order, cut where the nearest centre changes for good.
std::vector<Span> segment_spans(std::span<const double> x, const std::vector<double>& centers, const std::string& where,
                                FrictionMap& map) {
    const std::size_t n = x.size();
    std::vector<int> nearest(n);
    for (std::size_t k = 0; k < n; ++k) {
        const auto upper = std::lower_bound(centers.begin(), centers.end(), x[k]);
        std::size_t index = static_cast<std::size_t>(upper - centers.begin());
        if (index == centers.size() || (index > 0 && x[k] - centers[index - 1] < centers[index] - x[k])) --index;
        nearest[k] = static_cast<int>(index);
    }
    std::vector<Span> spans;
    for (std::size_t c = 0; c < centers.size(); ++c) {
        const auto first = std::find(nearest.begin(), nearest.end(), static_cast<int>(c));
        if (first == nearest.end()) {
            map.findings.push_back(
                fmt::format("centre {}: the trace never comes near it", position_text(centers[c], map)));
            continue;
        }
        const auto last = std::find(nearest.rbegin(), nearest.rend(), static_cast<int>(c));
        spans.push_back({static_cast<int>(c), static_cast<std::size_t>(first - nearest.begin()),
                         static_cast<std::size_t>(nearest.rend() - last)});
    }
    std::sort(spans.begin(), spans.end(), [](const Span& a, const Span& b) { return a.first < b.first; });
    for (std::size_t s = 0; s + 1 < spans.size(); ++s) {
        if (spans[s].last > spans[s + 1].first) {
            throw InputError(
                fmt::format("{}: the test returns to centre {} after visiting centre {}; the friction map needs one "
                            "visit per centre (cut the trace with --from/--to, or give other --centers).",
                            where, position_text(centers[static_cast<std::size_t>(spans[s].center)], map),
                            position_text(centers[static_cast<std::size_t>(spans[s + 1].center)], map)));
        }
        spans[s].last = spans[s + 1].first;  // the samples between two visits go to the earlier segment
    }
    return spans;
}

/// Identifies each segment, from its first to its last turning point.
void identify_segments(const Trace& trace, std::span<const double> x, const std::vector<double>& centers,
                       std::vector<Span> spans, const FrictionMapOptions& options, FrictionMap& map) {
    // Each segment from its first to its last turning point: the positioning moves from and to the other centres
    // are left out. They are the fastest motion in a segment, so they would weigh most on the viscous friction, and
    // they run over stretches of the axis that belong to no centre's strokes.
    const auto turns = turning_points(x, options.turning_hysteresis);
    for (auto& span : spans) {
        const auto first = std::lower_bound(turns.begin(), turns.end(), span.first);
        const auto end = std::lower_bound(turns.begin(), turns.end(), span.last);
        if (end - first >= 2) {
            span.first = *first;
            span.last = *(end - 1) + 1;
        }
    }

    const auto time = trace.column(Role::time);
    for (const auto& span : spans) {
        LocationResult location;
        location.center = centers[static_cast<std::size_t>(span.center)];
        location.first = span.first;
        location.last = span.last;
        location.from_s = time[span.first];
        location.to_s = time[span.last - 1];
        const auto [low, high] = std::minmax_element(x.begin() + static_cast<std::ptrdiff_t>(span.first),
                                                     x.begin() + static_cast<std::ptrdiff_t>(span.last));
        location.min_position = *low;
        location.max_position = *high;
        try {
            Trace segment = trace.slice(span.first, span.last);
            location.result = identify(segment, options.identify);
        } catch (const InputError& e) {
            location.error = e.what();
            location.result.status = Status::failed;
        } catch (const AnalysisError& e) {
            location.error = e.what();
            location.result.status = Status::failed;
        }
        map.locations.push_back(std::move(location));
    }
}

/// Which locations stand out: each parameter against the median over the locations.
void find_outstanding(const FrictionMapOptions& options, FrictionMap& map, std::vector<nlohmann::json>& deviations,
                      std::vector<std::vector<std::string>>& stands_out) {
    std::vector<std::string> keys;
    for (const auto& location : map.locations) {
        for (const auto& parameter : location.result.parameters) {
            if (parameter.estimate.value && std::find(keys.begin(), keys.end(), parameter.key) == keys.end())
                keys.push_back(parameter.key);
        }
    }
    deviations.assign(map.locations.size(), nlohmann::json::object());
    stands_out.assign(map.locations.size(), {});
    for (const auto& key : keys) {
        std::vector<double> values;
        std::vector<double> errors;
        for (const auto& location : map.locations) {
            const auto* parameter = location.result.find(key);
            if (parameter == nullptr || !parameter->estimate.value) continue;
            values.push_back(*parameter->estimate.value);
            if (parameter->estimate.standard_error) errors.push_back(*parameter->estimate.standard_error);
        }
        if (values.size() < 2) continue;
        const double typical = median(values);
        const double typical_error = errors.empty() ? 0.0 : median(errors);
        for (std::size_t l = 0; l < map.locations.size(); ++l) {
            const auto& location = map.locations[l];
            const auto* parameter = location.result.find(key);
            if (parameter == nullptr || !parameter->estimate.value || typical == 0.0) continue;
            const double value = *parameter->estimate.value;
            const double difference = value - typical;
            deviations[l][key] = 100.0 * difference / std::abs(typical);
            const double error = parameter->estimate.standard_error.value_or(0.0);
            const double combined = std::sqrt(error * error + typical_error * typical_error);
            if (std::abs(difference) > options.deviation_threshold * std::abs(typical) &&
                std::abs(difference) > 3.0 * combined) {
                stands_out[l].push_back(key);
                map.findings.push_back(
                    fmt::format("centre {}: {} = {:.4g} {} is {:.1f} % {} the median {:.4g} of the {} locations",
                                position_text(location.center, map), parameter->symbol, value, parameter->unit,
                                100.0 * std::abs(difference) / std::abs(typical), difference > 0.0 ? "above" : "below",
                                typical, values.size()));
            }
        }
    }
}

/// The friction-map document.
nlohmann::json map_document(const Trace& trace, const FrictionMapOptions& options, const FrictionMap& map,
                            const std::vector<nlohmann::json>& deviations,
                            const std::vector<std::vector<std::string>>& stands_out) {
    nlohmann::json locations = nlohmann::json::array();
    const std::string length = ParameterNaming{map.rotary}.length_key_suffix();
    for (std::size_t l = 0; l < map.locations.size(); ++l) {
        const auto& location = map.locations[l];
        nlohmann::json entry{{"center" + length, location.center},
                             {"from_s", location.from_s},
                             {"to_s", location.to_s},
                             {"samples", location.last - location.first},
                             {"position_min" + length, location.min_position},
                             {"position_max" + length, location.max_position},
                             {"status", location.result.status},
                             {"deviation_pct", deviations[l]},
                             {"stands_out", stands_out[l]}};
        const nlohmann::json document = location.result;
        entry["parameters"] = document.contains("parameters") ? document["parameters"] : nlohmann::json::object();
        if (document.contains("fit")) entry["fit"] = document["fit"];
        entry["diagnostics"] = location.result.diagnostics;
        if (location.error) entry["diagnostics"].push_back(*location.error);
        locations.push_back(std::move(entry));
    }
    const auto base = trace.time_base();
    return {{"feedid_version", version},
            {"trace",
             {{"path", trace.source_path},
              {"samples", trace.samples()},
              {"sample_time_s", finite_or_null(base.sample_time_s)},
              {"duration_s", finite_or_null(base.duration_s)}}},
            {"model", options.identify.model == FrictionModelKind::asymmetric ? "asymmetric" : "symmetric"},
            {"centers_detected", map.centers_detected},
            {"rotary", map.rotary},
            {"locations", locations},
            {"findings", map.findings}};
}

/// Every location is identified with one model, or the locations could not be compared key by key: where the model is
/// left to the data, it is chosen (with the drive signal's delay) on the whole trace and then given to each location.
FrictionMapOptions with_one_model(const Trace& trace, const FrictionMapOptions& options) {
    FrictionMapOptions chosen = options;
    IdentifyOptions& o = chosen.identify;
    if (!o.model_selection.automatic) return chosen;
    o.model_selection.automatic = false;
    o.model_selection.test_forced = false;
    o.model_selection.delay = ModelSelectionOptions::Delay::none;
    IdentifyOptions whole = options.identify;
    whole.systematic = false;
    try {
        const IdentifyResult result = identify(trace, whole);
        if (result.status == Status::failed || !result.model_choice) return chosen;
        o.model = result.model;
        o.offset = result.offset;
        if (result.model_choice->delay_applied) o.model_selection.known_delay_s = result.model_choice->delay_s;
    } catch (const InputError&) {
        // the locations say what is wrong with the data, each for its own
    } catch (const AnalysisError&) {
    }
    return chosen;
}

}  // namespace

FrictionMap friction_map(const Trace& trace, const FrictionMapOptions& options) {
    if (auto problem = options.validate(); !problem.empty()) throw InputError("friction map: " + problem + ".");
    const std::string where = trace.source_path.empty() ? std::string("trace") : trace.source_path;
    FrictionMap map;
    map.rotary = trace.rotary;
    const std::vector<double> centers = map_centers(trace, options, where, map);
    const auto x = stroke_signal(trace);
    const FrictionMapOptions chosen = with_one_model(trace, options);
    identify_segments(trace, x, centers, segment_spans(x, centers, where, map), chosen, map);
    std::vector<nlohmann::json> deviations;
    std::vector<std::vector<std::string>> stands_out;
    find_outstanding(chosen, map, deviations, stands_out);
    map.document = map_document(trace, chosen, map, deviations, stands_out);
    return map;
}

}  // namespace feedid
