#pragma once
// The names the command line and the Python module give the choices of IdentifyOptions and GainOptions
// (`--differentiation savitzky-golay`, `feedid.identify(..., rls="paper")`), so that both accept the same words and
// both show the options' defaults by the name of the value the library's Options struct holds.

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "feedid/identify/gains.hpp"
#include "feedid/identify/preprocess.hpp"
#include "feedid/identify/step1.hpp"
#include "feedid/numeric/rls.hpp"

namespace feedid {

template <class Enum>
struct NamedChoice {
    const char* name;
    Enum value;
};

/// The model left to the data (ModelSelectionOptions::automatic) rather than forced.
inline constexpr const char* automatic_model_name = "auto";
inline constexpr std::array<NamedChoice<FrictionModelKind>, 2> friction_model_names{
    {{"symmetric", FrictionModelKind::symmetric}, {"asymmetric", FrictionModelKind::asymmetric}}};
inline constexpr std::array<NamedChoice<Differentiation>, 3> differentiation_names{
    {{"butterworth", Differentiation::butterworth},
     {"central", Differentiation::central},
     {"savitzky-golay", Differentiation::savitzky_golay}}};
inline constexpr std::array<NamedChoice<VelocitySource>, 3> velocity_source_names{
    {{"auto", VelocitySource::automatic},
     {"position", VelocitySource::position},
     {"velocity", VelocitySource::logged}}};
inline constexpr std::array<NamedChoice<RlsVariant>, 2> rls_variant_names{
    {{"directional", RlsVariant::directional}, {"paper", RlsVariant::exponential}}};
inline constexpr std::array<NamedChoice<VelocityLoopStructure>, 3> velocity_loop_names{
    {{"auto", VelocityLoopStructure::automatic}, {"p", VelocityLoopStructure::p}, {"pi", VelocityLoopStructure::pi}}};

/// The name of `value` in `names`.
template <class Enum, std::size_t N>
std::string name_of(const std::array<NamedChoice<Enum>, N>& names, Enum value) {
    for (const auto& choice : names)
        if (choice.value == value) return choice.name;
    return {};
}

/// The value named `name`, nullopt for a name not in `names`.
template <class Enum, std::size_t N>
std::optional<Enum> value_named(const std::array<NamedChoice<Enum>, N>& names, std::string_view name) {
    for (const auto& choice : names)
        if (name == choice.name) return choice.value;
    return std::nullopt;
}

/// Every name, in the table's order.
template <class Enum, std::size_t N>
std::vector<std::string> names_of(const std::array<NamedChoice<Enum>, N>& names) {
    std::vector<std::string> out;
    for (const auto& choice : names) out.emplace_back(choice.name);
    return out;
}

}  // namespace feedid
