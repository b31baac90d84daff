// `nrad info`: what an .nrad asset holds.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>
#include <nrad/eval.h>
#include <nrad/format.h>

#include "baker/cmd/commands.h"
#include "baker/util/atomic_file.h"

namespace nrad {

namespace {

int runInfo(const std::string& path) {
    std::vector<uint8_t> bytes;
    try {
        bytes = readFileBytes(path);
    } catch (const IoError& e) {
        std::fprintf(stderr, "nrad info: %s\n", e.what());
        return kExitBadInput;
    }
    format::Asset a;
    format::DecodeStatus st = format::decode(bytes.data(), bytes.size(), a);
    if (st != format::DecodeStatus::Ok) {
        std::fprintf(stderr, "nrad info: %s: %s\n", path.c_str(), format::decodeStatusString(st));
        return kExitBadInput;
    }
    const format::Topology& t = a.topology;
    std::string widths;
    for (uint32_t w : t.hiddenWidths) widths += std::to_string(w) + "-";
    std::printf("%s: nrad asset version %u.%u, %zu bytes, %u sections\n", path.c_str(), a.header.versionMajor,
                a.header.versionMinor, bytes.size(), a.header.sectionCount);
    std::printf("grid: %ux%ux%u voxels over [%g, %g, %g] - [%g, %g, %g]\n", a.grid.dims[0], a.grid.dims[1], a.grid.dims[2],
                a.grid.lower[0], a.grid.lower[1], a.grid.lower[2], a.grid.upper[0], a.grid.upper[1], a.grid.upper[2]);
    if (a.tree.empty()) {
        std::printf("occupied voxels: %zu of %llu\n", a.voxels.size(), (unsigned long long)a.grid.voxelCount());
    } else {
        std::vector<format::TreeBox> boxes;
        uint32_t leaves = 0;
        format::validateTree(a.grid.dims, a.tree, leaves, &boxes);
        uint64_t smallest = UINT64_MAX, largest = 0;
        for (const format::TreeBox& b : boxes) {
            const uint64_t v = uint64_t(b.hi[0] - b.lo[0]) * (b.hi[1] - b.lo[1]) * (b.hi[2] - b.lo[2]);
            smallest = std::min(smallest, v);
            largest = std::max(largest, v);
        }
        const size_t hard = format::hardPlanes(a.tree);
        std::printf("partition: kd-tree of %u leaves over the grid's lattice (%zu nodes, %zu bytes, %zu hard planes with no "
                    "blending across), %zu with a network; leaves of %llu to %llu lattice voxels\n",
                    leaves, a.tree.size(), 4 + 8 * a.tree.size(), hard, a.voxels.size(), (unsigned long long)smallest,
                    (unsigned long long)largest);
    }
    std::printf("network: %u-%s%u, ReLU, output %s, %llu parameters, weights %s (%llu bytes)\n", t.inputs, widths.c_str(),
                t.outputs, t.outputTransform == format::OutputTransform::Exponential ? "scale x (exp(y) - 1)" : "scale x max(0, y)",
                (unsigned long long)t.parameterCount(), t.weightEncoding == format::WeightEncoding::Float16 ? "fp16" : "fp32",
                (unsigned long long)(t.parameterCount() * t.bytesPerWeight() * a.voxels.size()));
    std::printf("stores: %s%s\n",
                (a.header.flags & format::kFlagScatteredRadiance) ? "scattered radiance L - Le (shading adds the surface's own emission)"
                                                                  : "outgoing radiance L (emission included)",
                (a.header.flags & format::kFlagDemodulated) ? ", divided by the surface's reflectance (shading multiplies it back)" : "");
    if (!a.volumeVoxels.empty())
        std::printf("volume: %zu of %llu cells with a network of the light for receivers not in the bake (E(x, n) / pi; %llu "
                    "bytes; output %s)\n",
                    a.volumeVoxels.size(), (unsigned long long)a.cellCount(),
                    (unsigned long long)(t.parameterCount() * t.bytesPerWeight() * a.volumeVoxels.size()),
                    a.volumeTransform() == format::OutputTransform::Exponential ? "scale x (exp(y) - 1)" : "scale x max(0, y)");
    else
        std::printf("volume: none (only the baked surfaces answer; bake --volume-points for moving objects)\n");
    if (!a.glossyVoxels.empty())
        std::printf("volume, glossy response: %zu cells with a network of what a receiver of roughness %.1f reflects towards a "
                    "viewer (%llu bytes)\n",
                    a.glossyVoxels.size(), double(eval::kGlossyRoughness),
                    (unsigned long long)(t.parameterCount() * t.bytesPerWeight() * a.glossyVoxels.size()));
    if (a.header.flags & format::kFlagBlended)
        std::printf("blending: neighbouring networks blended within %g voxels of every interior face (no seams)\n", a.grid.blendBand);
    else
        std::printf("blending: none (one network per point)\n");
    if (!a.metadata.empty()) {
        // The lighting the asset was baked under, and what the engine must add itself.
        nlohmann::json meta = nlohmann::json::parse(a.metadata, nullptr, false);
        if (meta.is_object() && meta.contains("bake") && meta["bake"].is_object()) {
            const nlohmann::json& bake = meta["bake"];
            if (bake.contains("environment") && bake["environment"].is_object())
                std::printf("environment: %s\n", bake["environment"].value("description", bake["environment"].value("kind", "none")).c_str());
            if (bake.contains("lighting") && bake["lighting"].is_object() && bake["lighting"].contains("sun"))
                std::printf("sun: towards %s, %g lux, %g degrees across\n", bake["lighting"]["sun"].dump().c_str(),
                            bake["lighting"].value("sun_illuminance", 0.0), bake["lighting"].value("sun_angle", 0.0));
        }
        if (meta.is_object() && meta.contains("engine_drawn_direct") && meta["engine_drawn_direct"].is_array()) {
            std::string lights;
            for (const nlohmann::json& l : meta["engine_drawn_direct"])
                lights += (lights.empty() ? "" : ", ") + l.value("name", std::string("?")) + " (light " + std::to_string(l.value("light", -1)) + ")";
            std::printf("direct light the engine draws: %s\n", lights.empty() ? "none (the asset holds every light's scattered light)" : lights.c_str());
        }
    }
    std::printf("metadata: %s\n", a.metadata.empty() ? "(none)" : a.metadata.c_str());
    return kExitOk;
}

}  // namespace

std::function<int()> addInfoCommand(CLI::App& app) {
    auto path = std::make_shared<std::string>();
    CLI::App* cmd = app.add_subcommand("info", "Print what an .nrad asset holds");
    cmd->add_option("asset", *path, "The .nrad file")->required();
    return [path]() { return runInfo(*path); };
}

}  // namespace nrad
