// One RLS update, 3 and 4 parameters, both variants: the target is at most 25 ns (40 million samples per second).
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "feedid/numeric/rls.hpp"

namespace {

template <int N>
std::vector<Eigen::Matrix<double, N, 1>> regressors(std::size_t n) {
    std::vector<Eigen::Matrix<double, N, 1>> out(n);
    for (std::size_t k = 0; k < n; ++k) {
        const double t = 1e-3 * static_cast<double>(k);
        const double v = 0.1 * std::sin(2.0 * t) + 0.05 * std::sin(7.3 * t);
        const double a = 0.2 * std::cos(2.0 * t) + 0.365 * std::cos(7.3 * t);
        Eigen::Matrix<double, N, 1> phi;
        phi(0) = a;
        phi(1) = v;
        phi(2) = v > 0 ? 1.0 : -1.0;
        if constexpr (N > 3) phi(3) = 1.0;
        out[k] = phi;
    }
    return out;
}

template <int N, feedid::RlsVariant Variant>
void BM_RlsUpdate(benchmark::State& state) {
    const auto phi = regressors<N>(4096);
    std::vector<double> y(phi.size());
    for (std::size_t k = 0; k < y.size(); ++k) y[k] = 95.0 * phi[k](0) + 203.0 * phi[k](1) + 20.4 * phi[k](2);
    feedid::Rls<N> rls(feedid::RlsOptions{0.99995, 1e6, Variant});
    std::size_t k = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(rls.update(phi[k], y[k]));
        k = (k + 1) & 4095;
    }
    benchmark::DoNotOptimize(rls.estimate());
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}

BENCHMARK(BM_RlsUpdate<3, feedid::RlsVariant::exponential>)->Name("RlsUpdate/3/paper");
BENCHMARK(BM_RlsUpdate<3, feedid::RlsVariant::directional>)->Name("RlsUpdate/3/directional");
BENCHMARK(BM_RlsUpdate<4, feedid::RlsVariant::exponential>)->Name("RlsUpdate/4/paper");
BENCHMARK(BM_RlsUpdate<4, feedid::RlsVariant::directional>)->Name("RlsUpdate/4/directional");

}  // namespace

BENCHMARK_MAIN();
