// The P-PI controller model: loop arithmetic, the velocity measurement, saturation with anti-windup, NC units.
#include <cmath>

#include "feedid/model/controller.hpp"
#include "testing.hpp"

namespace {

TEST(Controller, EmpsStructureIsAPPConfiguration) {
    // v = kp*kv*(qg - qm) - kv*dq/dt with dq/dt = (q_k - q_{k-2})/(2T): K_v = kp, K_p = kv*gtau, K_i = 0.
    const double kp = 160.18, kv = 243.45, gtau = 35.15, dt = 1e-3;
    feedid::ControllerModel model;
    model.position_gain_per_s = kp;
    model.velocity_gain_N_s_per_m = kv * gtau;
    model.velocity_difference_samples = 2;
    feedid::Controller controller(model, dt, dt);
    controller.reset(0.0);
    const double positions[] = {0.0, 1e-5, 3e-5, 6e-5};
    const double reference = 1e-4;
    double history[] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    for (int k = 0; k < 4; ++k) {
        history[k + 2] = positions[k];
        const double v_cmd = controller.position_step(reference, 0.0, positions[k]);
        const double force = controller.velocity_step(v_cmd, positions[k]);
        const double dq = (history[k + 2] - history[k]) / (2 * dt);
        const double expected = gtau * (kp * kv * (reference - positions[k]) - kv * dq);
        EXPECT_NEAR(force, expected, 1e-9 * std::abs(expected)) << "sample " << k;
        EXPECT_NEAR(controller.measured_velocity(), dq, 1e-12);
    }
}

TEST(Controller, PiVelocityLoopIntegratesTheError) {
    feedid::ControllerModel model;
    model.velocity_gain_N_s_per_m = 100.0;
    model.velocity_integral_gain_N_per_m = 1000.0;  // T_n = 0.1 s
    feedid::Controller controller(model, 1e-3, 1e-3);
    controller.reset(0.0, 5.0);
    // Constant velocity error 0.01 m/s at standstill: F = K_p*e + 5 + K_i*e*T*k
    for (int k = 1; k <= 10; ++k) {
        const double force = controller.velocity_step(0.01, 0.0);
        EXPECT_NEAR(force, 100.0 * 0.01 + 5.0 + 1000.0 * 0.01 * 1e-3 * k, 1e-12);
    }
    EXPECT_NEAR(*model.reset_time_s(), 0.1, 1e-15);
}

TEST(Controller, SaturationClampsAndStopsIntegrating) {
    feedid::ControllerModel model;
    model.velocity_gain_N_s_per_m = 1000.0;
    model.velocity_integral_gain_N_per_m = 1e5;
    model.saturation_N = 50.0;
    feedid::Controller controller(model, 1e-3, 1e-3);
    controller.reset(0.0);
    double force = 0.0;
    for (int k = 0; k < 1000; ++k) force = controller.velocity_step(1.0, 0.0);
    EXPECT_DOUBLE_EQ(force, 50.0);
    // No wind-up: as soon as the error reverses, the output leaves the limit.
    force = controller.velocity_step(-0.01, 0.0);
    EXPECT_LT(force, 50.0);
    EXPECT_GT(force, -50.0);
}

TEST(Controller, NcUnits) {
    feedid::ControllerModel model;
    model.position_gain_per_s = feedid::position_gain_from_kv(1.0);
    EXPECT_NEAR(model.position_gain_per_s, 16.6667, 1e-4);  // 1 (m/min)/mm = 1000/60 1/s
    EXPECT_NEAR(model.kv_m_per_min_per_mm(), 1.0, 1e-12);
    // 1 (m/min)/mm = (1/60 m/s) / (1e-3 m)
    EXPECT_DOUBLE_EQ(1.0 / feedid::m_per_min_per_mm_per_1_per_s, (1.0 / 60.0) / 1e-3);
    model.velocity_gain_N_s_per_m = 1.0;
    EXPECT_FALSE(model.reset_time_s());
}

TEST(Controller, ValidateNamesTheProblem) {
    feedid::ControllerModel model;
    EXPECT_NE(model.validate().find("velocity gain"), std::string::npos);
    model.velocity_gain_N_s_per_m = 1.0;
    EXPECT_EQ(model.validate(), "");
    model.velocity_difference_samples = 0;
    EXPECT_NE(model.validate().find("1 to 8"), std::string::npos);
    model.velocity_difference_samples = 1;
    model.saturation_N = -1.0;
    EXPECT_NE(model.validate().find("saturation"), std::string::npos);
}

}  // namespace
