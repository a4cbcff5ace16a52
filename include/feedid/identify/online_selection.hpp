#pragma once
// The offset selected first, then the windows judged by the model selected (scan's rule, for a stream too). Judged by
// the model without the offset, a vertical axis's windows that move both ways are bent or rejected by the weight and
// those that move one way carry it in F_C: the windows are chosen by the wrong model before the selection sees them.
// So the windows are judged twice: by the model without the offset (the cheap and usual case: its pool tests the
// offset and does not take it) and, where that pool takes the offset or cannot test it, by the model with it
// (OnlineOptions::judge_with_offset), whose own Wald test decides. scan judges twice by passing over the file twice
// (scan.cpp); a stream is not run twice, so SelectingIdentifier runs both identifiers side by side.

#include <cstddef>
#include <optional>
#include <span>

#include "feedid/identify/online_identifier.hpp"

namespace feedid {

/// Which judgement of the windows the estimate is of.
enum class OffsetJudgement {
    /// the windows judged by the model without the offset, with their own selection (the offset not taken; or no
    /// value, which a second judgement does not rescue: judged by one more parameter, the few windows that agree
    /// would be pooled)
    first,
    /// the windows judged by the model with the offset, which its own test takes
    with_offset,
    /// the windows judged by the model without the offset, and its estimate without the offset: the first
    /// judgement's pool took the offset, the second's (judged by the model with it) does not
    without_offset,
};

/// Whether the first judgement (windows judged without the offset, select_offset on) leaves the offset open: its pool
/// took the offset or could not test it, and gave a value.
[[nodiscard]] bool offset_needs_judging(const OnlineEstimate& first);

/// The rule, from the first judgement's estimate and the second's (judged by the model with the offset).
[[nodiscard]] OffsetJudgement offset_judgement(const OnlineEstimate& first, const OnlineEstimate& with_offset);

/// `without` (the first judgement's estimate of the model without the offset) with the offset's test of the windows
/// judged by the model with it: what the model selection reports in the `without_offset` case.
void take_offset_test(OnlineEstimate& without, const OnlineEstimate& with_offset);

/// Two online identifiers over the same samples, the windows judged by the model without the offset and by the model
/// with it, and the estimate of the judgement scan's rule selects (offset_judgement). With the offset forced, not
/// selected (select_offset false) or already judged with (judge_with_offset), one identifier. Twice the work and
/// the memory of one identifier otherwise; nothing allocated per sample.
class SelectingIdentifier {
public:
    explicit SelectingIdentifier(const OnlineOptions& options);

    void push(double t, double x, double force, bool use = true);
    void push(std::span<const double> t, std::span<const double> x, std::span<const double> force,
              std::span<const char> use = {});
    void flush();
    [[nodiscard]] OnlineEstimate estimate() const;
    /// The identifier of the windows judged by the model without the offset (the options' own).
    [[nodiscard]] const OnlineIdentifier& first() const { return first_; }
    /// The identifier of the windows judged by the model with the offset (none when one identifier suffices).
    [[nodiscard]] const OnlineIdentifier* with_offset() const { return with_offset_ ? &*with_offset_ : nullptr; }
    /// Whether these options judge the windows twice.
    [[nodiscard]] static bool judges_twice(const OnlineOptions& options);
    /// The memory the identifiers take at this sample time [bytes] (OnlineIdentifier::memory_bytes, once or twice).
    [[nodiscard]] static std::size_t memory_bytes(const OnlineOptions& options, double sample_time_s);

private:
    OnlineIdentifier first_;
    std::optional<OnlineIdentifier> with_offset_;
};

}  // namespace feedid
