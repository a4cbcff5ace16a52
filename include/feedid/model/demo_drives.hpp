#pragma once
// The demo drives, defined once: the truth of `feedid synth`, the nominal drive of `feedid plan`, the Python module's
// defaults and the tests that check against them.
//   linear: the paper's Grob G515 x axis (M 69.1 kg, B 54.2 N*s/m, F_C 742.8 N, F_B 946.2 N) with a
//           ball-screw-typical v_s = 5 mm/s; K_t 1.444 N*m/A (26.0 N*m at 18.0 A), lead 20 mm; K_v 2 (m/min)/mm,
//           K_p 40000 N*s/m, T_n 20 ms, current lag 0.3 ms, the force limit at twice the rated 18 A.
//   rotary: a direct-drive rotary table: J 2.0 kg*m^2, B 5.0 N*m*s/rad, F_C 20 N*m, F_B 26 N*m, v_s 0.05 rad/s;
//           K_t 2 N*m/A; K_v 2 (1000 deg/min)/deg, K_p 400 N*m*s/rad, T_n 20 ms; the torque limit at 100 A.

#include "feedid/model/controller.hpp"
#include "feedid/model/friction.hpp"

namespace feedid {

/// A drive of the demo: the axis, its controller (saturation included) and the motor constants.
struct DemoDrive {
    AxisModel axis;
    ControllerModel controller;
    double kt_Nm_per_A{0.0};  ///< motor torque constant [N*m/A]
    double lead_m{0.0};       ///< ball-screw lead [m]; unused on the rotary table (a direct drive)
    double gear_ratio{1.0};   ///< motor revolutions per screw (or table) revolution
};

/// The linear demo drive (rotary = false) or the rotary demo table (rotary = true).
DemoDrive demo_drive(bool rotary = false);

}  // namespace feedid
