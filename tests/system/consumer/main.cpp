// A feedid user's program: a synthetic recording of the demo drive, identified with the installed library. Prints
// the mass and Coulomb friction against the truth and exits 1 when either is off by more than 2 %.
#include <cmath>
#include <cstdio>
#include <optional>

#include "feedid/identify/identify.hpp"
#include "feedid/model/demo_drives.hpp"
#include "feedid/sim/synth.hpp"

int main() {
    const feedid::SynthSpec spec = feedid::demo_spec();
    const feedid::Trace trace = feedid::synthesize(spec);
    feedid::IdentifyOptions options;
    options.drive.force_constant = spec.force_constant_N_per_A();
    options.systematic = false;
    const feedid::IdentifyResult result = feedid::identify(trace, options);
    const feedid::DemoDrive truth = feedid::demo_drive();
    const feedid::Parameter* mass_parameter = result.find("mass_kg");
    const feedid::Parameter* coulomb_parameter = result.find("coulomb_N");
    const auto mass = mass_parameter ? mass_parameter->estimate.value : std::nullopt;
    const auto coulomb = coulomb_parameter ? coulomb_parameter->estimate.value : std::nullopt;
    if (!mass || !coulomb) {
        std::printf("no mass or Coulomb friction identified\n");
        return 1;
    }
    const double true_coulomb = truth.axis.friction.forward.coulomb;
    std::printf("M %.3f kg (true %.1f), F_C %.2f N (true %.1f)\n", *mass, truth.axis.mass, *coulomb, true_coulomb);
    const bool close = std::abs(*mass / truth.axis.mass - 1.0) < 0.02 && std::abs(*coulomb / true_coulomb - 1.0) < 0.02;
    return close ? 0 : 1;
}
