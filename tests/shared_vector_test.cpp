// SharedVectorOwner: shares keep what their frame wrote, and frames in flight cost no allocation.
#include "core/shared_vector.hpp"

#include <gtest/gtest.h>

#include <deque>
#include <set>
#include <vector>

namespace voxtier {
namespace {

// A path render's pattern: each frame writes the array (in place, or afresh) and hands out a
// share, which its caller holds while the next `inFlight` frames are written.
TEST(SharedVectorOwner, FramesInFlightReuseTheArraysTheyDropAndKeepTheirContents) {
    for (const int inFlight : {0, 1, 2}) {
        SharedVectorOwner<int> owner;
        std::deque<std::pair<SharedVector<int>, std::vector<int>>> held; // share, what it held
        std::set<const int*> buffers;
        for (int frame = 0; frame < 40; ++frame) {
            const bool afresh = frame % 3 == 0;
            std::vector<int>& a = afresh ? owner.fresh() : owner.writable();
            if (afresh) {
                ASSERT_TRUE(a.empty()) << "frame " << frame;
                a.assign(1000, frame);
            } else {
                // In place: the last frame's values, whatever shares are held.
                ASSERT_EQ(a.size(), 1000u);
                EXPECT_EQ(a, std::vector<int>(1000, frame - 1)) << "frame " << frame;
                for (int& v : a) v = frame;
            }
            if (frame >= 10) buffers.insert(a.data()); // after the first frames' allocations
            held.emplace_back(owner.share(), a);
            while (int(held.size()) > inFlight) {
                // What a share saw is what its frame wrote, through every later frame.
                EXPECT_EQ(held.front().first.copy(), held.front().second) << "frame " << frame;
                held.pop_front();
            }
        }
        for (const auto& [share, wrote] : held) EXPECT_EQ(share.copy(), wrote);
        // One array per frame in flight and the one written: no allocation once warm.
        EXPECT_LE(buffers.size(), std::size_t(inFlight + 1)) << inFlight << " in flight";
    }
}

// A caller that keeps every share: each keeps its contents, and the owner lets go of the arrays
// it cannot reuse instead of collecting them.
TEST(SharedVectorOwner, SharesKeptForeverKeepTheirContents) {
    SharedVectorOwner<int> owner;
    std::vector<SharedVector<int>> all;
    for (int frame = 0; frame < 20; ++frame) {
        std::vector<int>& a = owner.writable();
        a.assign(std::size_t(frame + 1), frame);
        all.push_back(owner.share());
    }
    for (int frame = 0; frame < 20; ++frame)
        EXPECT_EQ(all[std::size_t(frame)].copy(), std::vector<int>(std::size_t(frame + 1), frame));
}

} // namespace
} // namespace voxtier
