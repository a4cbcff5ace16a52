#include "feedid/model/friction.hpp"

namespace feedid {

FrictionLaw FrictionBranch::law() const {
    if (!has_stribeck()) return {viscous, coulomb, 0.0, 0.0};
    return {viscous, coulomb, *breakaway - coulomb, 1.0 / *stribeck_velocity};
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
