// Owen-scrambled Sobol sampler: stratification of (0,2)-sequence prefixes, decorrelation, determinism.
#include "baker/render/sampler.h"

#include <set>
#include <vector>

#include <gtest/gtest.h>

namespace nrad {
namespace {

TEST(Sampler, FirstTwoSobolDimensionsKnownValues) {
    // Unscrambled Sobol points 0..3 in dimensions 0 and 1: (0,0), (.5,.5), (.75,.25), (.25,.75).
    EXPECT_EQ(sobolDim0(1), 0x80000000u);
    EXPECT_EQ(sobolDim1(1), 0x80000000u);
    EXPECT_EQ(sobolDim0(2), 0x40000000u);
    EXPECT_EQ(sobolDim1(2), 0xC0000000u);
    EXPECT_EQ(sobolDim0(3), 0xC0000000u);
    EXPECT_EQ(sobolDim1(3), 0x40000000u);
}

// The second dimension's shift-and-mask form against its definition, the XOR of the direction numbers
// v_0 = 1 << 31, v_k = v_{k-1} ^ (v_{k-1} >> 1) of the index's set bits: every index below 2^20, every single
// bit, all ones and a hashed spread over the rest.
TEST(Sampler, SecondDimensionIsTheDirectionNumbersDefinition) {
    uint32_t v[32];
    v[0] = 1u << 31;
    for (int k = 1; k < 32; ++k) v[k] = v[k - 1] ^ (v[k - 1] >> 1);
    auto definition = [&](uint32_t index) {
        uint32_t r = 0;
        for (int k = 0; k < 32; ++k)
            if ((index >> k) & 1u) r ^= v[k];
        return r;
    };
    std::vector<uint32_t> indices;
    for (uint32_t i = 0; i < (1u << 20); ++i) indices.push_back(i);
    for (int k = 0; k < 32; ++k) indices.push_back(1u << k);
    indices.push_back(0xffffffffu);
    for (uint32_t i = 0; i < 100000; ++i) indices.push_back(hashU32(i));
    for (uint32_t index : indices) {
        ASSERT_EQ(sobolDim1(index), definition(index)) << index;
        ASSERT_EQ(sobolDim1Reversed(index), reverseBits(definition(index))) << index;
    }
}

TEST(Sampler, EveryElementaryIntervalHoldsOnePoint) {
    // The first 256 points of any stream form a scrambled (0,8,2)-net: each of the 9 shapes of elementary
    // interval of area 1/256 (1x256, 2x128, ..., 256x1) contains exactly one point.
    for (uint32_t stream : {0u, 12345u, 0xdeadbeefu}) {
        std::vector<glm::vec2> pts;
        for (uint32_t i = 0; i < 256; ++i) {
            Sampler s(stream, i);
            s.get1D();  // skip one dimension: padded dimensions must be nets too
            pts.push_back(s.get2D());
        }
        for (int bx = 0; bx <= 8; ++bx) {
            int nx = 1 << bx, ny = 256 >> bx;
            std::set<int> cells;
            for (const glm::vec2& p : pts) cells.insert(int(p.x * nx) * ny + int(p.y * ny));
            EXPECT_EQ(cells.size(), 256u) << "stream " << stream << " shape " << nx << "x" << ny;
        }
    }
}

TEST(Sampler, StreamsAreDecorrelatedAndReproducible) {
    Sampler a(pixelStream(3, 4, 0), 5), b(pixelStream(3, 4, 0), 5), c(pixelStream(4, 3, 0), 5), d(pixelStream(3, 4, 1), 5);
    float va = a.get1D();
    EXPECT_EQ(va, b.get1D());
    EXPECT_NE(va, c.get1D());
    EXPECT_NE(va, d.get1D());
    // Mean of many 1D values of one stream is 1/2 (stratified, so very close).
    double sum = 0.0;
    for (uint32_t i = 0; i < 4096; ++i) sum += Sampler(77, i).get1D();
    EXPECT_NEAR(sum / 4096.0, 0.5, 1e-3);
}

// The sampler's shortened scramble of dimension 0 (two bit reversals fewer) gives the bits of the plain
// definition, Owen scrambling of the Sobol points: every value, for many streams, indices and dimensions.
TEST(Sampler, ShortenedScrambleEqualsTheDefinition) {
    for (uint32_t stream : {0u, 1u, 0xdeadbeefu, 0x12345678u}) {
        for (uint32_t index = 0; index < 2000; index += 7) {
            Sampler fast(stream, index);
            for (uint32_t dim = 0; dim < 8; ++dim) {
                const uint32_t seed = hashCombine(stream, dim);
                const uint32_t i = nestedUniformScramble(index, seed);
                const glm::vec2 plain(toUnitFloat(nestedUniformScramble(sobolDim0(i), seed * 0x9e3779b9u + 0x632be5abu)),
                                      toUnitFloat(nestedUniformScramble(sobolDim1(i), seed * 0x85ebca6bu + 0x2c1b3c6du)));
                if (dim % 3 == 2) {
                    ASSERT_EQ(fast.get1D(), plain.x) << stream << " " << index << " " << dim;
                } else {
                    const glm::vec2 v = fast.get2D();
                    ASSERT_EQ(v.x, plain.x) << stream << " " << index << " " << dim;
                    ASSERT_EQ(v.y, plain.y) << stream << " " << index << " " << dim;
                }
            }
        }
    }
}

// The batched draw (SIMD lanes over samplers, a clone per instruction set on x86-64) against get2D calls,
// one to three per sampler: the same bits for every batch size up to past two of its 64-sampler chunks,
// samplers at different dimensions, and each advanced as the calls advance it.
// next2D (the GFNI kernel where the CPU has it) and next2DWithoutGfni (the compiler-vectorised clones) alike.
TEST(Sampler, BatchedDrawsAreTheCallsBitForBit) {
    for (auto draw : {&next2D, &next2DWithoutGfni}) {
        for (size_t n : {size_t(1), size_t(3), size_t(63), size_t(64), size_t(65), size_t(200)}) {
            std::vector<Sampler> batched, single;
            for (size_t k = 0; k < n; ++k) {
                batched.emplace_back(hashU32(uint32_t(k) * 7u + 1u), uint32_t(k * 977u + (k << 20)));
                for (size_t skip = 0; skip < k % 5; ++skip) batched.back().get2D();
            }
            single = batched;
            std::vector<Sampler*> pointers;
            for (Sampler& s : batched) pointers.push_back(&s);
            std::vector<glm::vec2> out(3 * n);
            for (int round = 0; round < 3; ++round) {
                const uint32_t count = uint32_t(1 + (round + int(n)) % 3);
                draw(pointers.data(), n, count, out.data());
                for (size_t k = 0; k < n; ++k) {
                    for (uint32_t j = 0; j < count; ++j) {
                        const glm::vec2 u = single[k].get2D();
                        ASSERT_EQ(out[count * k + j].x, u.x) << "n " << n << ", sampler " << k << ", draw " << j;
                        ASSERT_EQ(out[count * k + j].y, u.y) << "n " << n << ", sampler " << k << ", draw " << j;
                    }
                    ASSERT_EQ(batched[k].dimension(), single[k].dimension());
                }
            }
        }
    }
}

}  // namespace
}  // namespace nrad
