// The .nrad asset byte layout: constants, the header and section records, the CRC, and a decoder that
// checks every offset, size and CRC against the buffer it is given. This file is the single definition of
// the bytes shared by the baker's writer and the runtime's reader; nrad/eval.h defines what the networks in
// them compute. docs/format.md specifies both. Only the C++17 standard library.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "nrad/check.h"

namespace nrad::format {

// ----- constants ------------------------------------------------------------------------------------------

// PNG-style magic: catches text-mode transfers (CR LF, ^Z) as well as wrong files.
constexpr std::array<uint8_t, 8> kMagic = {'N', 'R', 'A', 'D', 0x0D, 0x0A, 0x1A, 0x0A};
constexpr uint16_t kVersionMajor = 2;  // a reader rejects any other major version (1: networks stored L)
constexpr uint16_t kVersionMinor = 6;  // a reader accepts newer minors (new optional sections only); 2.1: blending,
                                       // 2.2: the kd-tree partition (TREE), 2.3: planes no band crosses (TreeNode::hard),
                                       // 2.4: the light in the volume (VVOX, VWGT), 2.5: its glossy response (VGLX, VGLW),
                                       // 2.6: the volume's networks decoded exponentially (kFlagVolumeExponential)

// Header flags: what the networks store (nrad/eval.h, shade()). A reader rejects unknown flags.
constexpr uint32_t kFlagScatteredRadiance = 1u;  // L - Le: the surface's own emission is added when shading
constexpr uint32_t kFlagDemodulated = 2u;  // divided by the surface's reflectance, multiplied back when shading
// Neighbouring networks are blended in a band around the voxel faces (Grid::blendBand, nrad/eval.h supports()).
// A 2.0 reader rejects the flag rather than draw the seams.
constexpr uint32_t kFlagBlended = 4u;
// The grid's lattice is partitioned by a kd-tree (TREE section) and VOXL indexes its leaves, not the
// lattice's voxels. A 2.0 or 2.1 reader rejects the flag rather than read leaf indices as voxels.
constexpr uint32_t kFlagTree = 8u;
// The volume's networks (VVOX) decode through OutputTransform::Exponential, whatever the topology's (which the
// surfaces and the glossy response keep); only with VVOX. A 2.5 reader rejects the flag rather than read them as
// linear. Without it the volume decodes as the topology says (2.4, 2.5).
constexpr uint32_t kFlagVolumeExponential = 16u;
constexpr uint32_t kKnownFlags = kFlagScatteredRadiance | kFlagDemodulated | kFlagBlended | kFlagTree | kFlagVolumeExponential;
constexpr float kMaxBlendBand = 0.5f;  // the band's half-width, in voxels: bands of opposite faces never overlap

constexpr uint32_t kHeaderSize = 64;
constexpr uint32_t kSectionRecordSize = 32;
constexpr uint32_t kSectionAlignment = 8;
constexpr uint32_t kMaxSections = 64;
constexpr uint32_t kMaxHiddenLayers = 8;
constexpr uint32_t kMaxHiddenWidth = 256;
constexpr uint32_t kInputCount = 9;  // position in voxel (3), normal (3), direction (3)
constexpr uint32_t kOutputCount = 3;  // RGB radiance
constexpr uint32_t kMaxGridDim = 1024;
constexpr uint32_t kMaxTreeNodes = 1u << 22;
constexpr uint32_t kMaxTreeDepth = 48;  // nodes from the root to the deepest leaf, the root not counted

constexpr uint32_t fourcc(char a, char b, char c, char d) {
    return uint32_t(uint8_t(a)) | (uint32_t(uint8_t(b)) << 8) | (uint32_t(uint8_t(c)) << 16) | (uint32_t(uint8_t(d)) << 24);
}
constexpr uint32_t kSectionGrid = fourcc('G', 'R', 'I', 'D');
constexpr uint32_t kSectionTopology = fourcc('T', 'O', 'P', 'O');
constexpr uint32_t kSectionVoxels = fourcc('V', 'O', 'X', 'L');
constexpr uint32_t kSectionWeights = fourcc('W', 'G', 'H', 'T');
constexpr uint32_t kSectionMetadata = fourcc('M', 'E', 'T', 'A');
constexpr uint32_t kSectionTree = fourcc('T', 'R', 'E', 'E');
constexpr uint32_t kSectionVolumeVoxels = fourcc('V', 'V', 'O', 'X');
constexpr uint32_t kSectionVolumeWeights = fourcc('V', 'W', 'G', 'T');
constexpr uint32_t kSectionGlossyVoxels = fourcc('V', 'G', 'L', 'X');
constexpr uint32_t kSectionGlossyWeights = fourcc('V', 'G', 'L', 'W');

enum class Activation : uint32_t { ReLU = 1 };
// How the last layer's value y becomes radiance: L = scale * max(0, y), or L = scale * (exp(y) - 1) for
// networks trained in log space (never negative either way; scale is the voxel's).
enum class OutputTransform : uint32_t { ClampedLinear = 0, Exponential = 1 };
enum class WeightEncoding : uint32_t { Float32 = 0, Float16 = 1 };

// ----- records (little-endian on disk; these structs only document field order, the codec below reads and
// writes field by field so host padding and endianness never matter) --------------------------------------

struct Header {  // 64 bytes at offset 0
    // 0: magic[8]; 8: u16 versionMajor; 10: u16 versionMinor; 12: u32 flags (kFlag*); 16: u32 headerSize (64);
    // 20: u32 sectionCount; 24: u64 fileSize; 32: u64 sectionTableOffset; 40: u32 CRC-32 of the section
    // table; 44..59: reserved (0); 60: u32 CRC-32 of bytes 0..59.
    uint16_t versionMajor = kVersionMajor;
    uint16_t versionMinor = kVersionMinor;
    uint32_t flags = 0;
    uint32_t sectionCount = 0;
    uint64_t fileSize = 0;
    uint64_t sectionTableOffset = kHeaderSize;
};

struct SectionRecord {  // 32 bytes each, sectionCount of them at sectionTableOffset
    // 0: u32 type (fourcc); 4: u32 flags (0); 8: u64 offset; 16: u64 size; 24: u32 CRC-32 of the section's
    // bytes; 28: u32 reserved (0).
    uint32_t type = 0;
    uint64_t offset = 0;
    uint64_t size = 0;
    uint32_t crc = 0;
};

struct Grid {  // GRID, 40 bytes: f32 lower[3], f32 upper[3], u32 dims[3], f32 blendBand
    float lower[3] = {0, 0, 0};
    float upper[3] = {1, 1, 1};
    uint32_t dims[3] = {1, 1, 1};
    // Half-width of the blending band around every interior face, in voxels: in (0, kMaxBlendBand] when the
    // header has kFlagBlended, else 0 (the bytes were reserved, 0, in format 2.0).
    float blendBand = 0.0f;
    uint64_t voxelCount() const { return uint64_t(dims[0]) * dims[1] * dims[2]; }
};

struct Topology {  // TOPO: u32 inputs, u32 outputs, u32 hiddenLayers, u32 activation, u32 outputTransform,
                   // u32 weightEncoding, u32 hiddenWidth[hiddenLayers]
    uint32_t inputs = kInputCount;
    uint32_t outputs = kOutputCount;
    std::vector<uint32_t> hiddenWidths = {9};
    Activation activation = Activation::ReLU;
    OutputTransform outputTransform = OutputTransform::ClampedLinear;
    WeightEncoding weightEncoding = WeightEncoding::Float16;

    // Parameters of one network: per layer, W (out x in, row-major) then b (out).
    uint64_t parameterCount() const {
        uint64_t n = 0, in = inputs;
        for (uint32_t w : hiddenWidths) {
            n += uint64_t(w) * in + w;
            in = w;
        }
        return n + uint64_t(outputs) * in + outputs;
    }
    uint32_t bytesPerWeight() const { return weightEncoding == WeightEncoding::Float16 ? 2 : 4; }
};

// VOXL: u32 occupiedCount, then occupiedCount records of 8 bytes: u32 linear voxel index (strictly
// increasing), f32 output scale (finite, > 0). WGHT: the networks in VOXL order, parameterCount weights each,
// in the topology's encoding. META: UTF-8 JSON (optional).
// VVOX and VWGT (version 2.4, optional, both or neither): the volume's networks, laid out as VOXL and WGHT (the
// same topology and encoding, cells of the same partition, their own occupied list): for a point x anywhere in
// the scene's volume and a unit normal n, the radiance a white Lambertian receiver at x facing n scatters,
// E(x, n) / pi (nrad/eval.h, volume query). A 2.3 reader passes them over and loads the surfaces.
// VGLX and VGLW (version 2.5, optional, both or neither; only beside VVOX): the volume's glossy response, laid out
// the same: for x, n and a unit direction v towards the viewer, the radiance a GGX receiver of roughness
// eval::kGlossyRoughness and Fresnel 1 at x facing n reflects towards v, over eval::glossyAlbedo(n.v) (nrad/eval.h,
// glossy query). A 2.4 reader passes them over.
struct VoxelEntry {
    uint32_t index = 0;  // x + dims[0] * (y + dims[1] * z)
    float scale = 1.0f;
};

// TREE (with kFlagTree): u32 nodeCount, then nodeCount records of 8 bytes: u32 axis | split << 2, u32 child |
// hard << 31 (hard: an internal node's plane no blending band crosses, version 2.3; a 2.2 reader refuses it).
// Node 0 is the root and covers the whole lattice [0, dims[0]) x [0, dims[1]) x [0, dims[2]) (the grid's
// voxels as the unit). An internal node (axis 0, 1, 2) cuts its box with the plane at lattice coordinate
// `split` of that axis, strictly inside the box; its lower child is node `child`, the upper one child + 1,
// both after the node itself. A leaf (axis kTreeLeaf, split 0) holds its leaf index in `child`: leaves are
// numbered 0, 1, ... in depth-first order, lower child first. Every node is reached exactly once from the
// root, no leaf lies deeper than kMaxTreeDepth: the leaves tile the lattice without overlap. A uniform grid is
// the tree of decode's uniformTree(): its leaf indices are the voxels' linear indices.
constexpr uint32_t kTreeLeaf = 3;
constexpr uint32_t kTreeHardBit = 1u << 31;  // in the child word
struct TreeNode {
    uint32_t axis = kTreeLeaf;
    uint32_t split = 0;
    uint32_t child = 0;
    // An internal node whose plane separates what light does not cross (a wall the bake found between two
    // rooms): no blending band across it (nrad/eval.h treeBandWidths gives it width 0).
    bool hard = false;
};

// The hard nodes of a tree.
inline size_t hardPlanes(const std::vector<TreeNode>& nodes) {
    size_t n = 0;
    for (const TreeNode& node : nodes) n += node.hard ? 1 : 0;
    return n;
}

// A leaf's (or node's) box on the lattice: [lo, hi) per axis, in voxels of the grid.
struct TreeBox {
    uint32_t lo[3] = {0, 0, 0};
    uint32_t hi[3] = {0, 0, 0};
};

// ----- CRC-32 (IEEE 802.3, the zlib/PNG polynomial) ----------------------------------------------------

inline uint32_t crc32(const uint8_t* data, size_t size, uint32_t crc = 0) {
    static const auto table = [] {
        std::array<uint32_t, 256> t{};
        for (uint32_t i = 0; i < 256; ++i) {
            uint32_t c = i;
            for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
            t[i] = c;
        }
        return t;
    }();
    crc = ~crc;
    for (size_t i = 0; i < size; ++i) crc = table[(crc ^ data[i]) & 0xFFu] ^ (crc >> 8);
    return ~crc;
}

// ----- fp16 -----------------------------------------------------------------------------------------------

// IEEE 754 binary16, round to nearest even; finite inputs beyond the range saturate to +-65504.
inline uint16_t floatToHalf(float f) {
    uint32_t x;
    std::memcpy(&x, &f, 4);
    uint32_t sign = (x >> 16) & 0x8000u;
    uint32_t absx = x & 0x7FFFFFFFu;
    if (absx >= 0x7F800000u) return uint16_t(sign | (absx > 0x7F800000u ? 0x7E00u : 0x7C00u));  // NaN / Inf
    if (absx >= 0x477FF000u) return uint16_t(sign | 0x7BFFu);  // rounds to >= 65520: saturate
    if (absx < 0x38800000u) {  // subnormal half (or zero)
        if (absx < 0x33000000u) return uint16_t(sign);  // below half the smallest subnormal
        uint32_t mant = (absx & 0x007FFFFFu) | 0x00800000u;
        int shift = 126 - int(absx >> 23);  // 14..24
        uint32_t half = mant >> shift;
        uint32_t rem = mant & ((1u << shift) - 1u), mid = 1u << (shift - 1);
        if (rem > mid || (rem == mid && (half & 1u))) ++half;
        return uint16_t(sign | half);
    }
    uint32_t half = ((absx - 0x38000000u) >> 13);
    uint32_t rem = absx & 0x1FFFu;
    if (rem > 0x1000u || (rem == 0x1000u && (half & 1u))) ++half;
    return uint16_t(sign | half);
}

inline float halfToFloat(uint16_t h) {
    uint32_t sign = uint32_t(h & 0x8000u) << 16;
    uint32_t exp = (h >> 10) & 0x1Fu, mant = h & 0x3FFu;
    uint32_t x;
    if (exp == 0) {
        if (mant == 0) {
            x = sign;
        } else {  // subnormal: normalise
            int e = -1;
            do {
                ++e;
                mant <<= 1;
            } while (!(mant & 0x400u));
            x = sign | (uint32_t(112 - e) << 23) | ((mant & 0x3FFu) << 13);
        }
    } else if (exp == 31) {
        x = sign | 0x7F800000u | (mant << 13);
    } else {
        x = sign | ((exp + 112) << 23) | (mant << 13);
    }
    float f;
    std::memcpy(&f, &x, 4);
    return f;
}

// ----- decoding -------------------------------------------------------------------------------------------

enum class DecodeStatus {
    Ok = 0,
    Truncated,  // the buffer ends before a structure it announces
    BadMagic,
    UnsupportedVersion,  // another major version
    BadHeader,  // header size, flags, reserved bytes, or file size do not match
    HeaderCrcMismatch,
    BadSectionTable,  // a section outside the file, overlapping, misaligned, duplicated, or unknown required
    SectionCrcMismatch,
    MissingSection,  // GRID, TOPO, VOXL or WGHT absent
    BadGrid,  // non-finite or empty bounds, zero or huge dimensions, a blend band out of range
    BadTopology,  // unsupported sizes, activation, transform or encoding
    BadVoxels,  // count, ordering, range or scale of the voxel table
    BadWeights,  // wrong size, or a weight that is not finite
    TrailingBytes,  // bytes after the last section
    BadTree,  // TREE without kFlagTree (or the reverse), or a tree that is cyclic, shared, out of range, too
              // deep, or whose splits leave an empty or overlapping leaf
    BadVolume,  // VVOX without VWGT, VGLX without VGLW (or the reverse), VGLX or kFlagVolumeExponential without
                // VVOX, or either invalid as VOXL or WGHT would be
};

inline const char* decodeStatusString(DecodeStatus s) {
    switch (s) {
        case DecodeStatus::Ok: return "ok";
        case DecodeStatus::Truncated: return "truncated file";
        case DecodeStatus::BadMagic: return "not an .nrad asset (bad magic)";
        case DecodeStatus::UnsupportedVersion: return "unsupported format version";
        case DecodeStatus::BadHeader: return "invalid header";
        case DecodeStatus::HeaderCrcMismatch: return "header CRC mismatch (damaged file)";
        case DecodeStatus::BadSectionTable: return "invalid section table";
        case DecodeStatus::SectionCrcMismatch: return "section CRC mismatch (damaged file)";
        case DecodeStatus::MissingSection: return "a required section is missing";
        case DecodeStatus::BadGrid: return "invalid grid";
        case DecodeStatus::BadTopology: return "invalid or unsupported network topology";
        case DecodeStatus::BadVoxels: return "invalid voxel table";
        case DecodeStatus::BadWeights: return "invalid weights";
        case DecodeStatus::TrailingBytes: return "trailing bytes after the last section";
        case DecodeStatus::BadTree: return "invalid partition tree";
        case DecodeStatus::BadVolume: return "invalid volume networks";
    }
    return "unknown status";
}

// A decoded asset. Weights are converted to float; `networks` holds occupiedCount x parameterCount values.
struct Asset {
    Header header;
    Grid grid;
    Topology topology;
    std::vector<VoxelEntry> voxels;
    std::vector<float> weights;
    std::string metadata;  // JSON text, empty if the section is absent
    std::vector<TreeNode> tree;  // with kFlagTree: the partition; empty: the uniform grid
    uint32_t leafCount = 0;  // the tree's leaves (with kFlagTree), else 0
    // The volume's networks (VVOX, VWGT; empty: none): the same cells, topology and encoding as the surfaces', the
    // output transform Exponential with kFlagVolumeExponential (volumeTransform()).
    std::vector<VoxelEntry> volumeVoxels;
    std::vector<float> volumeWeights;
    // The volume's glossy response (VGLX, VGLW; empty: none; only with volume networks): likewise.
    std::vector<VoxelEntry> glossyVoxels;
    std::vector<float> glossyWeights;
    // How the volume's networks' outputs decode (kFlagVolumeExponential, else the topology's transform).
    OutputTransform volumeTransform() const {
        return (header.flags & kFlagVolumeExponential) ? OutputTransform::Exponential : topology.outputTransform;
    }
    // What VOXL indexes: the tree's leaves, or the grid's voxels.
    uint64_t cellCount() const { return tree.empty() ? grid.voxelCount() : uint64_t(leafCount); }
};

// Checks a tree against the lattice `dims` (the rules above) and counts its leaves; false if any rule is
// broken. `boxes`, if given, receives every leaf's lattice box in leaf order.
inline bool validateTree(const uint32_t dims[3], const std::vector<TreeNode>& nodes, uint32_t& leafCount,
                         std::vector<TreeBox>* boxes = nullptr) {
    leafCount = 0;
    if (nodes.empty() || nodes.size() > kMaxTreeNodes) return false;
    if (boxes) boxes->clear();
    std::vector<uint8_t> seen(nodes.size(), 0);
    struct Item {
        uint32_t node, depth;
        TreeBox box;
    };
    std::vector<Item> stack;
    Item root{0, 0, {}};
    for (int k = 0; k < 3; ++k) root.box.hi[k] = dims[k];
    stack.push_back(root);
    size_t reached = 0;
    while (!stack.empty()) {
        Item it = stack.back();
        stack.pop_back();
        if (seen[it.node]) return false;  // shared or cyclic
        seen[it.node] = 1;
        ++reached;
        const TreeNode& n = nodes[it.node];
        if (n.axis == kTreeLeaf) {
            if (n.split != 0 || n.child != leafCount || n.hard) return false;  // leaves numbered in depth-first order
            ++leafCount;
            if (boxes) boxes->push_back(it.box);
            continue;
        }
        if (n.axis > 2 || it.depth >= kMaxTreeDepth) return false;
        if (!(n.split > it.box.lo[n.axis] && n.split < it.box.hi[n.axis])) return false;  // an empty side
        if (n.child <= it.node || uint64_t(n.child) + 1 >= nodes.size()) return false;  // after the node, in range
        Item lower{n.child, it.depth + 1, it.box}, upper{n.child + 1, it.depth + 1, it.box};
        lower.box.hi[n.axis] = n.split;
        upper.box.lo[n.axis] = n.split;
        stack.push_back(upper);  // the lower child is visited first
        stack.push_back(lower);
    }
    return reached == nodes.size();  // no node left unreached
}

// The tree whose leaves are the uniform grid's voxels, leaf index = linear voxel index x + dims[0] (y + dims[1] z):
// z is halved down to single slabs first, then y, then x, at the midpoints (lower half rounded down).
inline std::vector<TreeNode> uniformTree(const uint32_t dims[3]) {
    std::vector<TreeNode> nodes(1);
    uint32_t leaves = 0;
    struct Build {
        std::vector<TreeNode>& nodes;
        uint32_t& leaves;
        void operator()(uint32_t at, TreeBox b) {
            for (int k = 2; k >= 0; --k) {
                if (b.hi[k] - b.lo[k] < 2) continue;
                const uint32_t mid = b.lo[k] + (b.hi[k] - b.lo[k]) / 2, child = uint32_t(nodes.size());
                nodes.resize(nodes.size() + 2);
                nodes[at] = {uint32_t(k), mid, child};
                TreeBox lower = b, upper = b;
                lower.hi[k] = mid;
                upper.lo[k] = mid;
                (*this)(child, lower);
                (*this)(child + 1, upper);
                return;
            }
            nodes[at] = {kTreeLeaf, 0, leaves++};
        }
    };
    TreeBox root;
    for (int k = 0; k < 3; ++k) root.hi[k] = dims[k];
    Build{nodes, leaves}(0, root);
    return nodes;
}

namespace detail {
inline uint16_t rd16(const uint8_t* p) { return uint16_t(p[0] | (p[1] << 8)); }
inline uint32_t rd32(const uint8_t* p) { return uint32_t(p[0]) | (uint32_t(p[1]) << 8) | (uint32_t(p[2]) << 16) | (uint32_t(p[3]) << 24); }
inline uint64_t rd64(const uint8_t* p) { return uint64_t(rd32(p)) | (uint64_t(rd32(p + 4)) << 32); }
inline float rdf32(const uint8_t* p) {
    uint32_t x = rd32(p);
    float f;
    std::memcpy(&f, &x, 4);
    return f;
}

// decode()'s phases, in the order it runs them (so a file broken in several ways reports the first).

// The header: magic, version, CRC, sizes; `tableEnd` receives the end of the section table.
inline DecodeStatus decodeHeader(const uint8_t* data, size_t size, Header& h, uint64_t& tableEnd) {
    if (size < kHeaderSize) return (size >= 8 && std::memcmp(data, kMagic.data(), 8) != 0) ? DecodeStatus::BadMagic : DecodeStatus::Truncated;
    if (std::memcmp(data, kMagic.data(), 8) != 0) return DecodeStatus::BadMagic;
    h.versionMajor = rd16(data + 8);
    h.versionMinor = rd16(data + 10);
    if (h.versionMajor != kVersionMajor) return DecodeStatus::UnsupportedVersion;
    if (crc32(data, 60) != rd32(data + 60)) return DecodeStatus::HeaderCrcMismatch;
    h.flags = rd32(data + 12);
    uint32_t headerSize = rd32(data + 16);
    h.sectionCount = rd32(data + 20);
    h.fileSize = rd64(data + 24);
    h.sectionTableOffset = rd64(data + 32);
    for (int i = 44; i < 60; ++i)
        if (data[i] != 0) return DecodeStatus::BadHeader;
    if (headerSize != kHeaderSize || (h.flags & ~kKnownFlags) != 0) return DecodeStatus::BadHeader;
    if (h.fileSize > size) return DecodeStatus::Truncated;
    if (h.fileSize < size) return DecodeStatus::TrailingBytes;
    if (h.sectionCount == 0 || h.sectionCount > kMaxSections || h.sectionTableOffset != kHeaderSize)
        return DecodeStatus::BadSectionTable;
    tableEnd = h.sectionTableOffset + uint64_t(h.sectionCount) * kSectionRecordSize;
    if (tableEnd > size) return DecodeStatus::Truncated;
    if (crc32(data + h.sectionTableOffset, size_t(tableEnd - h.sectionTableOffset)) != rd32(data + 40))
        return DecodeStatus::BadSectionTable;
    return DecodeStatus::Ok;
}

// Where a known section's bytes are (null: absent).
struct SectionSpan {
    const uint8_t* at = nullptr;
    uint64_t size = 0;
};
struct SectionSpans {
    SectionSpan grid, topo, voxl, wght, meta, tree, vvox, vwgt, vglx, vglw;
    SectionSpan* of(uint32_t type) {  // null for a type this version does not know
        switch (type) {
            case kSectionGrid: return &grid;
            case kSectionTopology: return &topo;
            case kSectionVoxels: return &voxl;
            case kSectionWeights: return &wght;
            case kSectionMetadata: return &meta;
            case kSectionTree: return &tree;
            case kSectionVolumeVoxels: return &vvox;
            case kSectionVolumeWeights: return &vwgt;
            case kSectionGlossyVoxels: return &vglx;
            case kSectionGlossyWeights: return &vglw;
            default: return nullptr;
        }
    }
};

// The section table: every record checked (layout, padding, CRC) and the known sections located.
inline DecodeStatus decodeSectionTable(const uint8_t* data, size_t size, const Header& h, uint64_t tableEnd, SectionSpans& spans) {
    uint64_t expectedOffset = (tableEnd + kSectionAlignment - 1) / kSectionAlignment * kSectionAlignment;
    uint64_t previousEnd = tableEnd;
    for (uint32_t i = 0; i < h.sectionCount; ++i) {
        const uint8_t* r = data + h.sectionTableOffset + uint64_t(i) * kSectionRecordSize;
        SectionRecord s;
        s.type = rd32(r);
        uint32_t flags = rd32(r + 4);
        s.offset = rd64(r + 8);
        s.size = rd64(r + 16);
        s.crc = rd32(r + 24);
        if (flags != 0 || rd32(r + 28) != 0) return DecodeStatus::BadSectionTable;
        // Sections follow the table in order, each at the next aligned offset: no gaps, no overlap, and the
        // alignment padding before a section is zero (no byte of the file escapes a check).
        if (s.offset != expectedOffset) return DecodeStatus::BadSectionTable;
        if (s.size > size || s.offset > size - s.size) return DecodeStatus::Truncated;
        for (uint64_t pad = i == 0 ? tableEnd : previousEnd; pad < s.offset; ++pad)
            if (data[pad] != 0) return DecodeStatus::BadSectionTable;
        previousEnd = s.offset + s.size;
        if (crc32(data + s.offset, size_t(s.size)) != s.crc) return DecodeStatus::SectionCrcMismatch;
        expectedOffset = (s.offset + s.size + kSectionAlignment - 1) / kSectionAlignment * kSectionAlignment;
        SectionSpan* slot = spans.of(s.type);
        // Unknown sections are allowed (newer minor versions) but must not repeat known ones.
        if (!slot) continue;
        if (slot->at) return DecodeStatus::BadSectionTable;  // duplicated
        slot->at = data + s.offset;
        slot->size = s.size;
    }
    {
        const uint8_t* last = data + h.sectionTableOffset + uint64_t(h.sectionCount - 1) * kSectionRecordSize;
        if (rd64(last + 8) + rd64(last + 16) != size) return DecodeStatus::TrailingBytes;
    }
    if (!spans.grid.at || !spans.topo.at || !spans.voxl.at || !spans.wght.at) return DecodeStatus::MissingSection;
    return DecodeStatus::Ok;
}

// GRID: the box, the lattice and the blend band (present exactly with kFlagBlended).
inline DecodeStatus decodeGrid(SectionSpan grid, uint32_t flags, Grid& g) {
    if (grid.size != 40) return DecodeStatus::BadGrid;
    for (int k = 0; k < 3; ++k) {
        g.lower[k] = rdf32(grid.at + 4 * k);
        g.upper[k] = rdf32(grid.at + 12 + 4 * k);
        g.dims[k] = rd32(grid.at + 24 + 4 * k);
        if (!std::isfinite(g.lower[k]) || !std::isfinite(g.upper[k]) || !(g.upper[k] > g.lower[k]) ||
            !std::isfinite(g.upper[k] - g.lower[k]) || g.dims[k] == 0 || g.dims[k] > kMaxGridDim)
            return DecodeStatus::BadGrid;
        // The voxel rule's factor dims / (upper - lower) must be finite too (a subnormal extent is not).
        if (!std::isfinite(float(g.dims[k]) / (g.upper[k] - g.lower[k]))) return DecodeStatus::BadGrid;
    }
    g.blendBand = rdf32(grid.at + 36);
    if ((flags & kFlagBlended) ? !(g.blendBand > 0.0f && g.blendBand <= kMaxBlendBand) : rd32(grid.at + 36) != 0)
        return DecodeStatus::BadGrid;
    return DecodeStatus::Ok;
}

// TOPO: the network's shape, activation, output transform and weight encoding.
inline DecodeStatus decodeTopology(SectionSpan topo, Topology& t) {
    if (topo.size < 24) return DecodeStatus::BadTopology;
    t.inputs = rd32(topo.at);
    t.outputs = rd32(topo.at + 4);
    uint32_t layers = rd32(topo.at + 8);
    uint32_t act = rd32(topo.at + 12), transform = rd32(topo.at + 16), enc = rd32(topo.at + 20);
    if (t.inputs != kInputCount || t.outputs != kOutputCount || layers == 0 || layers > kMaxHiddenLayers ||
        topo.size != 24 + 4 * uint64_t(layers) || act != uint32_t(Activation::ReLU) || transform > 1 || enc > 1)
        return DecodeStatus::BadTopology;
    t.activation = Activation(act);
    t.outputTransform = OutputTransform(transform);
    t.weightEncoding = WeightEncoding(enc);
    t.hiddenWidths.resize(layers);
    for (uint32_t l = 0; l < layers; ++l) {
        t.hiddenWidths[l] = rd32(topo.at + 24 + 4 * l);
        if (t.hiddenWidths[l] == 0 || t.hiddenWidths[l] > kMaxHiddenWidth) return DecodeStatus::BadTopology;
    }
    return DecodeStatus::Ok;
}

// TREE: the partition, the uniform grid (no section) or (kFlagTree) a kd-tree over its lattice whose leaves
// VOXL indexes.
inline DecodeStatus decodeTree(SectionSpan tree, uint32_t flags, const Grid& g, std::vector<TreeNode>& nodes, uint32_t& leafCount) {
    if (((flags & kFlagTree) != 0) != (tree.at != nullptr)) return DecodeStatus::BadTree;
    if (!tree.at) return DecodeStatus::Ok;
    if (tree.size < 4) return DecodeStatus::BadTree;
    const uint32_t count = rd32(tree.at);
    if (count == 0 || count > kMaxTreeNodes || tree.size != 4 + 8 * uint64_t(count)) return DecodeStatus::BadTree;
    nodes.resize(count);
    for (uint32_t i = 0; i < count; ++i) {
        const uint32_t word = rd32(tree.at + 4 + 8 * uint64_t(i));
        const uint32_t child = rd32(tree.at + 8 + 8 * uint64_t(i));
        nodes[i] = {word & 3u, word >> 2, child & ~kTreeHardBit, (child & kTreeHardBit) != 0};
    }
    if (!validateTree(g.dims, nodes, leafCount)) return DecodeStatus::BadTree;
    return DecodeStatus::Ok;
}

// VOXL: the occupied cells of `cells`, in increasing order, each with a finite positive scale.
inline DecodeStatus decodeVoxels(SectionSpan voxl, uint64_t cells, std::vector<VoxelEntry>& voxels) {
    if (voxl.size < 4) return DecodeStatus::BadVoxels;
    uint32_t occupied = rd32(voxl.at);
    if (occupied == 0 || occupied > cells || voxl.size != 4 + 8 * uint64_t(occupied)) return DecodeStatus::BadVoxels;
    voxels.resize(occupied);
    for (uint32_t i = 0; i < occupied; ++i) {
        voxels[i].index = rd32(voxl.at + 4 + 8 * uint64_t(i));
        voxels[i].scale = rdf32(voxl.at + 8 + 8 * uint64_t(i));
        if (voxels[i].index >= cells || (i > 0 && voxels[i].index <= voxels[i - 1].index) ||
            !std::isfinite(voxels[i].scale) || !(voxels[i].scale > 0.0f))
            return DecodeStatus::BadVoxels;
    }
    return DecodeStatus::Ok;
}

// WGHT: every network's weights, as floats, each finite.
inline DecodeStatus decodeWeights(SectionSpan wght, const Topology& t, uint32_t occupied, std::vector<float>& weights) {
    uint64_t params = t.parameterCount();
    if (wght.size != uint64_t(occupied) * params * t.bytesPerWeight()) return DecodeStatus::BadWeights;
    weights.resize(size_t(uint64_t(occupied) * params));
    for (size_t i = 0; i < weights.size(); ++i) {
        float w = t.weightEncoding == WeightEncoding::Float16 ? halfToFloat(rd16(wght.at + 2 * i)) : rdf32(wght.at + 4 * i);
        if (!std::isfinite(w)) return DecodeStatus::BadWeights;
        weights[i] = w;
    }
    return DecodeStatus::Ok;
}
}  // namespace detail

// Decodes and validates an asset held in [data, data + size). Safe on untrusted input: every offset and
// count is checked against the buffer before use, every CRC is verified, every weight must be finite.
inline DecodeStatus decode(const uint8_t* data, size_t size, Asset& out) {
    using namespace detail;
    Header h;
    uint64_t tableEnd = 0;
    SectionSpans spans;
    Grid g;
    Topology t;
    std::vector<TreeNode> nodes;
    uint32_t leafCount = 0;
    if (DecodeStatus s = decodeHeader(data, size, h, tableEnd); s != DecodeStatus::Ok) return s;
    if (DecodeStatus s = decodeSectionTable(data, size, h, tableEnd, spans); s != DecodeStatus::Ok) return s;
    if (DecodeStatus s = decodeGrid(spans.grid, h.flags, g); s != DecodeStatus::Ok) return s;
    if (DecodeStatus s = decodeTopology(spans.topo, t); s != DecodeStatus::Ok) return s;
    if (DecodeStatus s = decodeTree(spans.tree, h.flags, g, nodes, leafCount); s != DecodeStatus::Ok) return s;
    const uint64_t cells = spans.tree.at ? uint64_t(leafCount) : g.voxelCount();
    std::vector<VoxelEntry> voxels;
    if (DecodeStatus s = decodeVoxels(spans.voxl, cells, voxels); s != DecodeStatus::Ok) return s;
    std::vector<float> weights;
    if (DecodeStatus s = decodeWeights(spans.wght, t, uint32_t(voxels.size()), weights); s != DecodeStatus::Ok) return s;
    std::vector<VoxelEntry> volumeVoxels;
    std::vector<float> volumeWeights;
    if ((spans.vvox.at != nullptr) != (spans.vwgt.at != nullptr)) return DecodeStatus::BadVolume;
    if ((h.flags & kFlagVolumeExponential) && !spans.vvox.at) return DecodeStatus::BadVolume;
    if (spans.vvox.at) {
        if (decodeVoxels(spans.vvox, cells, volumeVoxels) != DecodeStatus::Ok) return DecodeStatus::BadVolume;
        if (decodeWeights(spans.vwgt, t, uint32_t(volumeVoxels.size()), volumeWeights) != DecodeStatus::Ok) return DecodeStatus::BadVolume;
    }
    std::vector<VoxelEntry> glossyVoxels;
    std::vector<float> glossyWeights;
    if ((spans.vglx.at != nullptr) != (spans.vglw.at != nullptr) || (spans.vglx.at && !spans.vvox.at)) return DecodeStatus::BadVolume;
    if (spans.vglx.at) {
        if (decodeVoxels(spans.vglx, cells, glossyVoxels) != DecodeStatus::Ok) return DecodeStatus::BadVolume;
        if (decodeWeights(spans.vglw, t, uint32_t(glossyVoxels.size()), glossyWeights) != DecodeStatus::Ok) return DecodeStatus::BadVolume;
    }

    out.header = h;
    out.grid = g;
    out.topology = std::move(t);
    out.voxels = std::move(voxels);
    out.weights = std::move(weights);
    out.metadata = spans.meta.at ? std::string(reinterpret_cast<const char*>(spans.meta.at), size_t(spans.meta.size)) : std::string();
    out.tree = std::move(nodes);
    out.leafCount = leafCount;
    out.volumeVoxels = std::move(volumeVoxels);
    out.volumeWeights = std::move(volumeWeights);
    out.glossyVoxels = std::move(glossyVoxels);
    out.glossyWeights = std::move(glossyWeights);
    return DecodeStatus::Ok;
}

// ----- encoding -------------------------------------------------------------------------------------------

namespace detail {
inline void wr16(std::vector<uint8_t>& b, uint16_t v) { b.push_back(uint8_t(v)); b.push_back(uint8_t(v >> 8)); }
inline void wr32(std::vector<uint8_t>& b, uint32_t v) { for (int i = 0; i < 4; ++i) b.push_back(uint8_t(v >> (8 * i))); }
inline void wr64(std::vector<uint8_t>& b, uint64_t v) { for (int i = 0; i < 8; ++i) b.push_back(uint8_t(v >> (8 * i))); }
inline void wrf32(std::vector<uint8_t>& b, float f) {
    uint32_t x;
    std::memcpy(&x, &f, 4);
    wr32(b, x);
}
inline void put32(std::vector<uint8_t>& b, size_t at, uint32_t v) { for (int i = 0; i < 4; ++i) b[at + size_t(i)] = uint8_t(v >> (8 * i)); }
inline void put64(std::vector<uint8_t>& b, size_t at, uint64_t v) { for (int i = 0; i < 8; ++i) b[at + size_t(i)] = uint8_t(v >> (8 * i)); }
}  // namespace detail

// The size encode() gives an asset of `networks` networks of topology t, a tree of `treeNodes` nodes (0: no
// TREE section), `metadataBytes` of metadata (0: no META section), `volumeNetworks` of the volume's (0: no
// VVOX and VWGT) and `glossyNetworks` of its glossy response (0: no VGLX and VGLW): for writers that must fit a
// byte budget.
inline uint64_t encodedSize(const Topology& t, uint64_t networks, uint64_t treeNodes, uint64_t metadataBytes,
                            uint64_t volumeNetworks = 0, uint64_t glossyNetworks = 0) {
    const uint64_t perNetwork = t.parameterCount() * t.bytesPerWeight();
    const uint64_t sections[10] = {40, 24 + 4 * uint64_t(t.hiddenWidths.size()), 4 + 8 * networks, networks * perNetwork,
                                   treeNodes ? 4 + 8 * treeNodes : 0, volumeNetworks ? 4 + 8 * volumeNetworks : 0,
                                   volumeNetworks * perNetwork, glossyNetworks ? 4 + 8 * glossyNetworks : 0,
                                   glossyNetworks * perNetwork, metadataBytes};
    const bool present[10] = {true, true, true, true, treeNodes > 0, volumeNetworks > 0, volumeNetworks > 0,
                              glossyNetworks > 0, glossyNetworks > 0, metadataBytes > 0};
    uint64_t count = 0;
    for (bool p : present) count += p ? 1 : 0;
    uint64_t size = kHeaderSize + count * kSectionRecordSize;
    for (int i = 0; i < 10; ++i)
        if (present[i]) size = (size + kSectionAlignment - 1) / kSectionAlignment * kSectionAlignment + sections[i];
    return size;
}

// Encodes an asset as given, without checking it (header.flags as given, version and sizes from this file):
// for writing invalid assets on purpose (the decoder's tests). Writers use encode().
inline std::vector<uint8_t> encodeUnchecked(const Asset& a) {
    using namespace detail;
    std::vector<std::vector<uint8_t>> sections;
    std::vector<uint32_t> types;
    {
        std::vector<uint8_t> s;
        for (int k = 0; k < 3; ++k) wrf32(s, a.grid.lower[k]);
        for (int k = 0; k < 3; ++k) wrf32(s, a.grid.upper[k]);
        for (int k = 0; k < 3; ++k) wr32(s, a.grid.dims[k]);
        wrf32(s, (a.header.flags & kFlagBlended) ? a.grid.blendBand : 0.0f);
        sections.push_back(std::move(s));
        types.push_back(kSectionGrid);
    }
    {
        std::vector<uint8_t> s;
        const Topology& t = a.topology;
        wr32(s, t.inputs);
        wr32(s, t.outputs);
        wr32(s, uint32_t(t.hiddenWidths.size()));
        wr32(s, uint32_t(t.activation));
        wr32(s, uint32_t(t.outputTransform));
        wr32(s, uint32_t(t.weightEncoding));
        for (uint32_t w : t.hiddenWidths) wr32(s, w);
        sections.push_back(std::move(s));
        types.push_back(kSectionTopology);
    }
    const auto voxelSection = [](const std::vector<VoxelEntry>& voxels) {
        std::vector<uint8_t> s;
        wr32(s, uint32_t(voxels.size()));
        for (const VoxelEntry& v : voxels) {
            wr32(s, v.index);
            wrf32(s, v.scale);
        }
        return s;
    };
    const auto weightSection = [&a](const std::vector<float>& weights) {
        std::vector<uint8_t> s;
        for (float w : weights) {
            if (a.topology.weightEncoding == WeightEncoding::Float16)
                wr16(s, floatToHalf(w));
            else
                wrf32(s, w);
        }
        return s;
    };
    sections.push_back(voxelSection(a.voxels));
    types.push_back(kSectionVoxels);
    sections.push_back(weightSection(a.weights));
    types.push_back(kSectionWeights);
    if (a.header.flags & kFlagTree) {
        std::vector<uint8_t> s;
        wr32(s, uint32_t(a.tree.size()));
        for (const TreeNode& n : a.tree) {
            wr32(s, n.axis | (n.split << 2));
            wr32(s, n.child | (n.hard ? kTreeHardBit : 0u));
        }
        sections.push_back(std::move(s));
        types.push_back(kSectionTree);
    }
    if (!a.volumeVoxels.empty()) {
        sections.push_back(voxelSection(a.volumeVoxels));
        types.push_back(kSectionVolumeVoxels);
        sections.push_back(weightSection(a.volumeWeights));
        types.push_back(kSectionVolumeWeights);
    }
    if (!a.glossyVoxels.empty()) {
        sections.push_back(voxelSection(a.glossyVoxels));
        types.push_back(kSectionGlossyVoxels);
        sections.push_back(weightSection(a.glossyWeights));
        types.push_back(kSectionGlossyWeights);
    }
    if (!a.metadata.empty()) {  // last, so that a borrowed buffer's metadata is its tail
        sections.emplace_back(a.metadata.begin(), a.metadata.end());
        types.push_back(kSectionMetadata);
    }

    std::vector<uint8_t> out(kHeaderSize, 0);
    std::memcpy(out.data(), kMagic.data(), 8);
    out[8] = uint8_t(kVersionMajor);
    out[9] = uint8_t(kVersionMajor >> 8);
    // The lowest minor version that describes the content, so that 2.0 readers still load unblended assets.
    const bool hard = (a.header.flags & kFlagTree) && hardPlanes(a.tree) > 0;
    const uint16_t minor = (a.header.flags & kFlagVolumeExponential) ? 6
                           : !a.glossyVoxels.empty()                ? 5
                           : !a.volumeVoxels.empty()                ? 4
                           : hard                                   ? 3
                           : (a.header.flags & kFlagTree)           ? 2
                           : (a.header.flags & kFlagBlended)        ? 1
                                                                    : 0;
    out[10] = uint8_t(minor);
    out[11] = uint8_t(minor >> 8);
    put32(out, 12, a.header.flags & kKnownFlags);
    put32(out, 16, kHeaderSize);
    put32(out, 20, uint32_t(sections.size()));
    put64(out, 32, kHeaderSize);
    size_t tableAt = out.size();
    out.resize(out.size() + sections.size() * kSectionRecordSize, 0);
    for (size_t i = 0; i < sections.size(); ++i) {
        while (out.size() % kSectionAlignment) out.push_back(0);
        size_t r = tableAt + i * kSectionRecordSize;
        put32(out, r, types[i]);
        put64(out, r + 8, out.size());
        put64(out, r + 16, sections[i].size());
        put32(out, r + 24, crc32(sections[i].data(), sections[i].size()));
        out.insert(out.end(), sections[i].begin(), sections[i].end());
    }
    put64(out, 24, out.size());
    put32(out, 40, crc32(out.data() + tableAt, sections.size() * kSectionRecordSize));
    put32(out, 60, crc32(out.data(), 60));
    return out;
}

// Encodes an asset (header.flags as given, version and sizes from this file). Its preconditions are checked
// (NRAD_CHECK: a writer that breaks one is a bug, stopped before it writes): weights.size() == voxels.size()
// x parameterCount, voxel indices strictly increasing and inside the grid (the tree's leaves with kFlagTree,
// whose tree is valid; the file records no leaf count, the reader counts them), all values finite, scales > 0. The output decodes to the
// same asset (weights rounded to the encoding).
inline std::vector<uint8_t> encode(const Asset& a) {
    NRAD_CHECK(a.weights.size() == a.voxels.size() * a.topology.parameterCount());
    uint32_t leaves = 0;
    if (a.header.flags & kFlagTree) NRAD_CHECK(validateTree(a.grid.dims, a.tree, leaves));
    const uint64_t cells = (a.header.flags & kFlagTree) ? uint64_t(leaves) : a.grid.voxelCount();
    for (size_t i = 0; i < a.voxels.size(); ++i) {
        NRAD_CHECK(a.voxels[i].index < cells && (i == 0 || a.voxels[i].index > a.voxels[i - 1].index));
        NRAD_CHECK(std::isfinite(a.voxels[i].scale) && a.voxels[i].scale > 0.0f);
    }
    for (float w : a.weights) NRAD_CHECK(std::isfinite(w));
    NRAD_CHECK(a.volumeWeights.size() == a.volumeVoxels.size() * a.topology.parameterCount());
    for (size_t i = 0; i < a.volumeVoxels.size(); ++i) {
        NRAD_CHECK(a.volumeVoxels[i].index < cells && (i == 0 || a.volumeVoxels[i].index > a.volumeVoxels[i - 1].index));
        NRAD_CHECK(std::isfinite(a.volumeVoxels[i].scale) && a.volumeVoxels[i].scale > 0.0f);
    }
    for (float w : a.volumeWeights) NRAD_CHECK(std::isfinite(w));
    NRAD_CHECK(a.glossyWeights.size() == a.glossyVoxels.size() * a.topology.parameterCount());
    NRAD_CHECK(a.glossyVoxels.empty() || !a.volumeVoxels.empty());
    NRAD_CHECK(!(a.header.flags & kFlagVolumeExponential) || !a.volumeVoxels.empty());
    for (size_t i = 0; i < a.glossyVoxels.size(); ++i) {
        NRAD_CHECK(a.glossyVoxels[i].index < cells && (i == 0 || a.glossyVoxels[i].index > a.glossyVoxels[i - 1].index));
        NRAD_CHECK(std::isfinite(a.glossyVoxels[i].scale) && a.glossyVoxels[i].scale > 0.0f);
    }
    for (float w : a.glossyWeights) NRAD_CHECK(std::isfinite(w));
    for (int k = 0; k < 3; ++k) NRAD_CHECK(std::isfinite(a.grid.lower[k]) && std::isfinite(a.grid.upper[k]));
    return encodeUnchecked(a);
}

}  // namespace nrad::format
