// Identify a drive from a recording: read it (any supported format, converted to SI), run the two steps, print each
// parameter with its standard error, or why the data could not tell.
//   example_01_identify ../shared/data/emps/DATA_EMPS.mat qm vir gtau
#include <cstdio>
#include <exception>

#include <fmt/core.h>

#include "feedid/core/error.hpp"
#include "feedid/identify/identify.hpp"
#include "feedid/io/import.hpp"

int main(int argc, char** argv) {
    if (argc != 5) {
        fmt::print(stderr, "usage: {} FILE POSITION_CHANNEL CURRENT_CHANNEL FORCE_CONSTANT_SCALAR\n", argv[0]);
        return 2;
    }
    try {
        feedid::ImportOptions import;
        import.channels = {{feedid::Role::position, argv[2]}, { feedid::Role::current, argv[3] }};
        const feedid::Trace trace = feedid::read_trace(argv[1], import);

        feedid::IdentifyOptions options;
        options.offset = true;
        options.drive.force_constant_name = argv[4];
        const feedid::IdentifyResult result = feedid::identify(trace, options);

        for (const auto& p : result.parameters) {
            if (p.estimate.value) {
                fmt::print("{:<6} {:>12.6g} ± {:<10.2g} {}\n", p.symbol, *p.estimate.value, *p.estimate.standard_error,
                           p.unit);
            } else {
                fmt::print("{:<6} {:>12}   {:<10} {}\n", p.symbol, "—", "", p.unit);
            }
        }
        for (const auto& d : result.diagnostics) fmt::print("note: {}\n", d);
        return result.status == feedid::Status::failed ? 1 : 0;
    } catch (const feedid::InputError& e) {
        fmt::print(stderr, "{}\n", e.what());
        return 2;
    }
}
