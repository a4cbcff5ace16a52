// The friction law of eq. (3): a branch and its unpacked form (what the simulator evaluates) are the same law.
#include <cmath>

#include "feedid/model/friction.hpp"
#include "testing.hpp"

namespace {

feedid::FrictionBranch stribeck_branch() {
    feedid::FrictionBranch branch;
    branch.viscous = 50.0;
    branch.coulomb = 100.0;
    branch.breakaway = 150.0;
    branch.stribeck_velocity = 0.002;
    return branch;
}

TEST(Friction, LawIsEquationThreeWithTheStribeckTermUnpacked) {
    const auto branch = stribeck_branch();
    const feedid::FrictionLaw law = branch.law();
    EXPECT_EQ(law.stribeck_rise, 50.0);
    EXPECT_EQ(law.inverse_stribeck_velocity, 500.0);
    EXPECT_EQ(law.magnitude(0.0), 150.0) << "F_B at 0+";
    for (const double speed : {1e-4, 0.002, 0.01, 0.5}) {
        const double expected = 50.0 * speed + 100.0 + 50.0 * std::exp(-speed / 0.002);
        EXPECT_NEAR(law.magnitude(speed), expected, 1e-12 * expected) << speed;
        EXPECT_EQ(branch.magnitude(speed), law.magnitude(speed)) << speed;
    }
}

TEST(Friction, WithoutAStribeckTermTheLawIsViscousPlusCoulomb) {
    feedid::FrictionBranch branch;
    branch.viscous = 20.0;
    branch.coulomb = 30.0;
    branch.breakaway = 40.0;  // no Stribeck velocity: no Stribeck term
    EXPECT_EQ(branch.law().stribeck_rise, 0.0);
    EXPECT_EQ(branch.magnitude(0.1), 20.0 * 0.1 + 30.0);
    branch.stribeck_velocity = 0.0;  // nor with v_s = 0
    EXPECT_FALSE(branch.has_stribeck());
    EXPECT_EQ(branch.magnitude(0.1), 20.0 * 0.1 + 30.0);
}

TEST(Friction, ForceIsSignedPerDirection) {
    feedid::Friction friction{stribeck_branch(), stribeck_branch()};
    friction.reverse.coulomb = 120.0;
    EXPECT_EQ(friction.force(0.01), friction.forward.magnitude(0.01));
    EXPECT_EQ(friction.force(-0.01), -friction.reverse.magnitude(0.01));
    EXPECT_EQ(friction.force(0.0), 0.0);
    EXPECT_EQ(friction.breakaway_force(true), 150.0);
    EXPECT_EQ(friction.breakaway_force(false), 150.0);
}

}  // namespace
