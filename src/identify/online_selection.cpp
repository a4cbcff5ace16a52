// The offset selected first, then the windows judged by the model selected (online_selection.hpp).

#include "feedid/identify/online_selection.hpp"

namespace feedid {

bool offset_needs_judging(const OnlineEstimate& first) {
    // a first judgement without a value stays refused: judged by a model with one more parameter, the few windows
    // that agree would be pooled (the EMPS recording, whose friction differs by direction: 2 of its 13 windows, B 156
    // +- 1.3 N*s/m against the 203.5 published)
    if (!first.mass.determined()) return false;
    return first.offset_in_model || !first.offset_statistic;
}

OffsetJudgement offset_judgement(const OnlineEstimate& first, const OnlineEstimate& with_offset) {
    if (!offset_needs_judging(first)) return OffsetJudgement::first;
    if (with_offset.offset_in_model) return OffsetJudgement::with_offset;
    return first.offset_in_model ? OffsetJudgement::without_offset : OffsetJudgement::first;
}

void take_offset_test(OnlineEstimate& without, const OnlineEstimate& with_offset) {
    without.offset_selected = true;
    without.offset_judged = true;
    without.offset_statistic = with_offset.offset_statistic;
    without.offset_estimate = with_offset.offset_estimate;
    without.offset_standard_error = with_offset.offset_standard_error;
    without.offset_threshold = with_offset.offset_threshold;
    without.offset_verdict = with_offset.offset_verdict;
}

bool SelectingIdentifier::judges_twice(const OnlineOptions& options) {
    return options.select_offset && !options.offset && !options.judge_with_offset;
}

SelectingIdentifier::SelectingIdentifier(const OnlineOptions& options) : first_(options) {
    if (!judges_twice(options)) return;
    OnlineOptions judged = options;
    judged.judge_with_offset = true;
    with_offset_.emplace(judged);
}

void SelectingIdentifier::push(double t, double x, double force, bool use) {
    first_.push(t, x, force, use);
    if (with_offset_) with_offset_->push(t, x, force, use);
}

void SelectingIdentifier::push(std::span<const double> t, std::span<const double> x, std::span<const double> force,
                               std::span<const char> use) {
    first_.push(t, x, force, use);
    if (with_offset_) with_offset_->push(t, x, force, use);
}

void SelectingIdentifier::flush() {
    first_.flush();
    if (with_offset_) with_offset_->flush();
}

OnlineEstimate SelectingIdentifier::estimate() const {
    OnlineEstimate first = first_.estimate();
    if (!with_offset_ || !offset_needs_judging(first)) return first;
    OnlineEstimate judged = with_offset_->estimate();
    switch (offset_judgement(first, judged)) {
        case OffsetJudgement::first: return first;
        case OffsetJudgement::with_offset: return judged;
        case OffsetJudgement::without_offset: break;
    }
    OnlineEstimate without = first_.estimate_without_offset();
    take_offset_test(without, judged);
    return without;
}

std::size_t SelectingIdentifier::memory_bytes(const OnlineOptions& options, double sample_time_s) {
    return (judges_twice(options) ? 2 : 1) * OnlineIdentifier::memory_bytes(options, sample_time_s);
}

}  // namespace feedid
