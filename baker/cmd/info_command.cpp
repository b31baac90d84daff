// `nrad info`: what an .nrad asset holds.
#include <cstdio>
#include <memory>
#include <string>

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
    std::printf("occupied voxels: %zu of %llu\n", a.voxels.size(), (unsigned long long)a.grid.voxelCount());
    std::printf("network: %u-%s%u, ReLU, output %s, %llu parameters, weights %s (%llu bytes)\n", t.inputs, widths.c_str(),
                t.outputs, t.outputTransform == format::OutputTransform::Exponential ? "scale x (exp(y) - 1)" : "scale x max(0, y)",
                (unsigned long long)t.parameterCount(), t.weightEncoding == format::WeightEncoding::Float16 ? "fp16" : "fp32",
                (unsigned long long)(t.parameterCount() * t.bytesPerWeight() * a.voxels.size()));
    std::printf("stores: %s%s\n",
                (a.header.flags & format::kFlagScatteredRadiance) ? "scattered radiance L - Le (shading adds the surface's own emission)"
                                                                  : "outgoing radiance L (emission included)",
                (a.header.flags & format::kFlagDemodulated) ? ", divided by the surface's reflectance (shading multiplies it back)" : "");
    if (a.header.flags & format::kFlagBlended)
        std::printf("blending: neighbouring networks blended within %g voxels of every interior face (no seams)\n", a.grid.blendBand);
    else
        std::printf("blending: none (one network per point)\n");
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
