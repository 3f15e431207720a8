// Time left of a job whose items run on a pool of worker threads, learnt from the items done
// (brdftool fit/recommend's progress line). Header-only: the tools and its unit test
// (shading/tests/eta_test.cpp) share it.
//
// Every item has a prior cost (a relative weight: what one family of models costs to fit
// compared with another, measured once) and, once it has run, its measured duration. The rate
// (seconds per unit of prior cost) is learnt from the measured durations of the items done,
// and from the items still running that have already taken longer than the rate predicts (a
// lower bound on their duration); the items left are then laid on the threads in the order
// the pool takes them (each to the thread that frees first) and the time left is when the last
// thread is done. So the estimate knows that the families still queued cost more than the ones
// done, that several run at once, and corrects the priors by what this machine actually takes.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

namespace shading_tools {

enum class ItemState { Queued, Running, Done };

// prior[k] > 0, state[k], seconds[k] (Done: its duration; Running: the time since it started;
// Queued: unused). Queued items are taken in index order. Returns NaN until an item is done.
inline double seconds_left(const std::vector<double>& prior, const std::vector<ItemState>& state,
                           const std::vector<double>& seconds, int threads) {
    const std::size_t n = prior.size();
    double t_done = 0, w_done = 0;
    for (std::size_t k = 0; k < n; ++k)
        if (state[k] == ItemState::Done) {
            t_done += seconds[k];
            w_done += prior[k];
        }
    if (!(w_done > 0)) return std::numeric_limits<double>::quiet_NaN();
    double rate = t_done / w_done;
    // Running items that already took longer than predicted: their elapsed time is a lower bound
    // of their duration, and raises the rate (censored durations; the others add nothing yet).
    double t_run = 0, w_run = 0;
    for (std::size_t k = 0; k < n; ++k)
        if (state[k] == ItemState::Running && seconds[k] > rate * prior[k]) {
            t_run += seconds[k];
            w_run += prior[k];
        }
    if (w_run > 0) rate = (t_done + t_run) / (w_done + w_run);

    std::vector<double> lane;  // when each thread is free, from now
    for (std::size_t k = 0; k < n; ++k)
        if (state[k] == ItemState::Running) {
            const double expect = rate * prior[k];
            // An item past its prediction ends at an unknown time: a tenth of its prediction more.
            lane.push_back(std::max(expect - seconds[k], 0.1 * expect));
        }
    const std::size_t pool = std::max<std::size_t>(std::size_t(std::max(threads, 1)), lane.size());
    lane.resize(pool, 0.0);
    for (std::size_t k = 0; k < n; ++k)
        if (state[k] == ItemState::Queued) {
            auto first_free = std::min_element(lane.begin(), lane.end());
            *first_free += rate * prior[k];
        }
    return *std::max_element(lane.begin(), lane.end());
}

}  // namespace shading_tools
