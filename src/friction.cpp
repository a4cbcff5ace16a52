#include "feedid/friction.hpp"

#include <cmath>

namespace feedid {

double FrictionBranch::magnitude(double speed) const {
    if (!has_stribeck()) return friction_magnitude(speed, viscous, coulomb, 0.0, 0.0);
    return friction_magnitude(speed, viscous, coulomb, *breakaway - coulomb, *stribeck_velocity);
}

double Friction::force(double velocity) const {
    if (velocity > 0.0) return forward.magnitude(velocity);
    if (velocity < 0.0) return -reverse.magnitude(-velocity);
    return 0.0;
}

double Friction::breakaway_force(bool forward_direction) const {
    const auto& branch = forward_direction ? forward : reverse;
    return branch.has_stribeck() ? *branch.breakaway : branch.coulomb;
}

}  // namespace feedid
