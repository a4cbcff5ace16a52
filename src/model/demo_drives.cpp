// The demo drives (demo_drives.hpp).
#include "feedid/model/demo_drives.hpp"

#include <numbers>

namespace feedid {

namespace {

// The linear demo's controller: K_v 2 (m/min)/mm, T_n 20 ms, current lag 0.3 ms, and K_p high enough that sliding is
// stable down to about 100 mm/min against the Stribeck slope (F_B - F_C)/v_s = 40 kN*s/m; below that the axis
// stick-slips, as real axes do. The force limit is twice the demo motor's rated 18 A.
constexpr double demo_kv_m_per_min_per_mm = 2.0;
constexpr double demo_velocity_gain_N_s_per_m = 40000.0;
constexpr double demo_integral_time_s = 0.020;
constexpr double demo_current_lag_s = 0.3e-3;
constexpr double demo_saturation_A = 36.0;
constexpr double demo_kt_Nm_per_A = 1.444;  // the paper's 26.0 N*m at 18.0 A
constexpr double demo_lead_m = 0.020;

// The rotary demo: K_p such that the velocity loop's crossover K_p/J = 200 rad/s keeps about 40 degrees of phase
// margin at a 2 ms cycle with a velocity measured over 4 ms, and above the Stribeck slope (F_B - F_C)/v_s =
// 120 N*m*s/rad; the torque limit at 100 A.
constexpr double rotary_demo_inertia_kgm2 = 2.0;
constexpr double rotary_demo_velocity_gain_Nms_per_rad = 400.0;
constexpr double rotary_demo_kt_Nm_per_A = 2.0;
constexpr double rotary_demo_saturation_A = 100.0;

DemoDrive linear_demo() {
    DemoDrive drive;
    FrictionBranch branch;
    branch.viscous = 54.2;
    branch.coulomb = 742.8;
    branch.breakaway = 946.2;
    branch.stribeck_velocity = 0.005;
    drive.axis.mass = 69.1;
    drive.axis.friction = Friction::symmetric(branch);
    drive.kt_Nm_per_A = demo_kt_Nm_per_A;
    drive.lead_m = demo_lead_m;
    drive.controller.position_gain_per_s = position_gain_from_kv(demo_kv_m_per_min_per_mm);
    drive.controller.velocity_gain_N_s_per_m = demo_velocity_gain_N_s_per_m;
    drive.controller.velocity_integral_gain_N_per_m = demo_velocity_gain_N_s_per_m / demo_integral_time_s;
    drive.controller.current_lag_s = demo_current_lag_s;
    // force per ampere = K_t * g * 2*pi / lead (eq. 2)
    drive.controller.saturation_N = demo_saturation_A * demo_kt_Nm_per_A * 2.0 * std::numbers::pi / demo_lead_m;
    return drive;
}

DemoDrive rotary_demo() {
    DemoDrive drive = linear_demo();
    FrictionBranch branch;
    branch.viscous = 5.0;
    branch.coulomb = 20.0;
    branch.breakaway = 26.0;
    branch.stribeck_velocity = 0.05;
    drive.axis.rotary = true;
    drive.axis.mass = rotary_demo_inertia_kgm2;
    drive.axis.friction = Friction::symmetric(branch);
    drive.kt_Nm_per_A = rotary_demo_kt_Nm_per_A;
    drive.controller.velocity_gain_N_s_per_m = rotary_demo_velocity_gain_Nms_per_rad;
    drive.controller.velocity_integral_gain_N_per_m = rotary_demo_velocity_gain_Nms_per_rad / demo_integral_time_s;
    drive.controller.saturation_N = rotary_demo_saturation_A * rotary_demo_kt_Nm_per_A;  // torque = K_t * g * i
    return drive;
}

}  // namespace

DemoDrive demo_drive(bool rotary) {
    return rotary ? rotary_demo() : linear_demo();
}

}  // namespace feedid
