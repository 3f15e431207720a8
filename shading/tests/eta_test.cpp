// brdftool's time left (shading/tools/eta.h): learnt from the items done, weighted by what the
// items left cost, spread over the threads (issue 33: the old estimate, elapsed / done x left,
// said 18 s left at 1 s and 71 s left at 29 s of a 79 s fit, because the cheap families come
// first).
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "../tools/eta.h"

using shading_tools::ItemState;
using shading_tools::seconds_left;

namespace {
constexpr ItemState Q = ItemState::Queued, R = ItemState::Running, D = ItemState::Done;
}

TEST(Eta, UnknownUntilAnItemIsDone) {
    EXPECT_TRUE(std::isnan(seconds_left({1, 1}, {Q, Q}, {0, 0}, 1)));
    EXPECT_TRUE(std::isnan(seconds_left({1, 1}, {R, Q}, {5, 0}, 1)));
}

TEST(Eta, EqualItemsOnOneAndTwoThreads) {
    EXPECT_DOUBLE_EQ(seconds_left({1, 1, 1, 1}, {D, D, Q, Q}, {1, 1, 0, 0}, 1), 2.0);
    EXPECT_DOUBLE_EQ(seconds_left({1, 1, 1, 1}, {D, D, Q, Q}, {1, 1, 0, 0}, 2), 1.0);
    EXPECT_DOUBLE_EQ(seconds_left({1, 1, 1}, {D, D, D}, {1, 1, 1}, 2), 0.0);
}

TEST(Eta, CostlierItemsLeftTakeLonger) {
    // Two cheap items done in 0.5 s each; the two left cost four times as much each.
    EXPECT_DOUBLE_EQ(seconds_left({1, 1, 4, 4}, {D, D, Q, Q}, {0.5, 0.5, 0, 0}, 1), 4.0);
    EXPECT_DOUBLE_EQ(seconds_left({1, 1, 4, 4}, {D, D, Q, Q}, {0.5, 0.5, 0, 0}, 2), 2.0);
}

TEST(Eta, LearnsTheMachinesSpeedFromItemsDone) {
    // The priors say 1 s per unit; this machine takes 3 s: after one item the estimate is 3x.
    EXPECT_DOUBLE_EQ(seconds_left({1, 2, 2}, {D, Q, Q}, {3, 0, 0}, 1), 12.0);
}

TEST(Eta, ARunningItemCountsWhatIsLeftOfIt) {
    // Rate 1 s per unit; an item of cost 4 running for 1 s has 3 s left, the queued one 4 s on
    // the other thread.
    EXPECT_DOUBLE_EQ(seconds_left({1, 4, 4}, {D, R, Q}, {1, 1, 0}, 2), 4.0);
    // One thread: the queued item waits for the running one.
    EXPECT_DOUBLE_EQ(seconds_left({1, 4, 4}, {D, R, Q}, {1, 1, 0}, 1), 7.0);
}

TEST(Eta, ARunningItemPastItsPredictionRaisesTheRate) {
    // Predicted 4 s (rate 1), running for 8 s already: the rate becomes (1 + 8) / (1 + 4) = 1.8
    // and the queued item of cost 4 is expected to take 7.2 s after it.
    const double left = seconds_left({1, 4, 4}, {D, R, Q}, {1, 8, 0}, 1);
    EXPECT_NEAR(left, 0.1 * 1.8 * 4 + 1.8 * 4, 1e-12);
}

TEST(Eta, TheIssuesFitIsEstimatedFromItsFirstSecond) {
    // A fit whose cheap families come first: priors proportional to the true costs, the
    // machine 2x slower than the priors. After the first item the estimate is the true time
    // left (in the old estimate, elapsed / done x left: far too low).
    const std::vector<double> cost = {0.2, 1, 3, 3, 10, 20, 5, 5, 5, 5};
    const double slow = 2.0;
    std::vector<ItemState> st(cost.size(), Q);
    std::vector<double> sec(cost.size(), 0.0);
    st[0] = D;
    sec[0] = slow * cost[0];
    double truth = 0;
    for (std::size_t k = 1; k < cost.size(); ++k) truth += slow * cost[k];
    EXPECT_NEAR(seconds_left(cost, st, sec, 1), truth, 1e-9 * truth);
    const double old = sec[0] / 1.0 * double(cost.size() - 1);
    EXPECT_LT(old, 0.05 * truth);
}
