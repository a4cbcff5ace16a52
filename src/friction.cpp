#include "feedid/friction.hpp"

#include <cmath>

namespace feedid {

double FrictionBranch::magnitude(double speed) const {
    // eq. (3): B*|v| + F_C + (F_B - F_C)*exp(-|v|/v_s)
    double value = viscous * speed + coulomb;
    if (has_stribeck()) value += (*breakaway - coulomb) * std::exp(-speed / *stribeck_velocity);
    return value;
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
