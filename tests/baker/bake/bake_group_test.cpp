// What the processes of a bake agree on without talking: their blocks of a list, the owners of networks by
// cost, and the bytes they exchange.
#include <numeric>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "baker/bake/bake_group.h"

namespace nrad {
namespace {

TEST(BakeGroup, BlockSharesTakeEveryItemOnceSpreadOverTheList) {
    for (size_t count : {0u, 1u, 99u, 100u, 101u, 1000u})
        for (int size : {1, 2, 3, 7}) {
            const BlockShares shares{count, 10, size};
            std::vector<int> owner(count, -1);
            for (int r = 0; r < size; ++r) {
                size_t last = 0;
                for (size_t j = 0; j < shares.blocksOf(r); ++j) {
                    const Share b = shares.blockOf(r, j);
                    EXPECT_LT(b.first, b.last) << count << " " << size << " " << r << " " << j;
                    EXPECT_GE(b.first, last);  // in order
                    last = b.last;
                    for (size_t i = b.first; i < b.last; ++i) {
                        EXPECT_EQ(owner[i], -1) << i;
                        owner[i] = r;
                    }
                }
            }
            for (size_t i = 0; i < count; ++i) EXPECT_EQ(owner[i], int((i / 10) % size_t(size))) << count << " " << size << " " << i;
        }
}

TEST(BakeGroup, LargestCostFirstToTheLeastLoadedProcess) {
    const std::vector<double> costs = {1.0, 10.0, 7.0, 9.0, 1.0, 8.0};
    const std::vector<int> owner = assignByCost(costs, 2);
    // Order: 10 (i1), 9 (i3), 8 (i5), 7 (i2), 1 (i0), 1 (i4). Loads: i1 -> 0 (10); i3 -> 1 (9); i5 -> 1 (17);
    // i2 -> 0 (17); i0 -> 0 (equal: lower rank; 18); i4 -> 1 (18).
    EXPECT_EQ(owner, (std::vector<int>{0, 0, 0, 1, 1, 1}));
    double load[2] = {0, 0};
    for (size_t i = 0; i < costs.size(); ++i) load[owner[i]] += costs[i];
    EXPECT_EQ(load[0], 18.0);
    EXPECT_EQ(load[1], 18.0);
    EXPECT_EQ(assignByCost(costs, 1), std::vector<int>(6, 0));
    EXPECT_EQ(assignByCost({}, 3), std::vector<int>{});
}

TEST(BakeGroup, BytesRoundTripAndATruncatedMessageIsRefused) {
    ByteWriter w;
    w.put(uint32_t(7));
    w.putVector(std::vector<float>{1.5f, -2.0f});
    w.putString("voxel 3: restarted");
    w.put(2.25);
    ByteReader in(w.bytes);
    EXPECT_EQ(in.get<uint32_t>(), 7u);
    EXPECT_EQ(in.getVector<float>(), (std::vector<float>{1.5f, -2.0f}));
    EXPECT_EQ(in.getString(), "voxel 3: restarted");
    EXPECT_EQ(in.get<double>(), 2.25);
    EXPECT_TRUE(in.done());
    std::vector<uint8_t> cut(w.bytes.begin(), w.bytes.end() - 3);
    ByteReader short_(cut);
    short_.get<uint32_t>();
    short_.getVector<float>();
    short_.getString();
    EXPECT_THROW(short_.get<double>(), std::runtime_error);
    ByteWriter h;  // a vector claiming more elements than there are bytes
    h.put(uint64_t(1) << 40);
    ByteReader lying(h.bytes);
    EXPECT_THROW(lying.getVector<float>(), std::runtime_error);
}

}  // namespace
}  // namespace nrad
