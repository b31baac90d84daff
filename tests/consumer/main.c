/* C99 consumer of the installed libnrad: loads an asset, queries it, evaluates one point and a batch.
 * Usage: consumer ASSET.nrad; exits 0 if everything behaves as documented. */
#include <math.h>
#include <stdio.h>

#include <nrad/nrad.h>

int main(int argc, char** argv) {
    NradAsset asset = NULL;
    char message[256];
    NradAssetInfo info;
    float p[3], n[3] = {0.0f, 0.0f, 1.0f}, d[3] = {0.0f, 0.0f, 1.0f}, rgb[3];
    uint32_t flags = 0;
    float positions[6], normals[6] = {0, 0, 1, 0, 0, 1}, directions[6] = {0, 0, 1, 0, 0, 1}, out[6];
    uint8_t pointFlags[2];
    NradStatus status;
    int k;
    if (argc != 2) {
        fprintf(stderr, "usage: consumer ASSET.nrad\n");
        return 2;
    }
    status = nradLoadFromFile(argv[1], &asset, message, sizeof message);
    if (status != NRAD_OK) {
        fprintf(stderr, "load failed: %s (%s)\n", nradStatusString(status), message);
        return 1;
    }
    if (nradGetAssetInfo(asset, &info) != NRAD_OK || info.inputs != 9 || info.outputs != 3 || info.occupiedVoxels == 0) {
        fprintf(stderr, "unexpected asset info\n");
        return 1;
    }
    /* The centre of the grid's last voxel along z is occupied in the golden asset. */
    for (k = 0; k < 3; ++k) p[k] = 0.5f * (info.gridLower[k] + info.gridUpper[k]);
    p[2] = info.gridUpper[2] - 0.25f * (info.gridUpper[2] - info.gridLower[2]) / (float)info.gridDims[2];
    status = nradEvaluate(asset, p, n, d, rgb, &flags);
    if (status != NRAD_OK || flags != NRAD_POINT_OK || !(rgb[0] >= 0.0f) || !isfinite(rgb[1])) {
        fprintf(stderr, "evaluate: %s, flags %u\n", nradStatusString(status), (unsigned)flags);
        return 1;
    }
    for (k = 0; k < 3; ++k) {
        positions[k] = p[k];
        positions[3 + k] = info.gridUpper[k] + 1.0f; /* outside */
    }
    status = nradEvaluateBatch(asset, 2, positions, normals, directions, out, pointFlags);
    if (status != NRAD_OK || pointFlags[0] != NRAD_POINT_OK || pointFlags[1] != NRAD_POINT_OUTSIDE_GRID || out[0] != rgb[0] ||
        out[3] != 0.0f) {
        fprintf(stderr, "batch mismatch\n");
        return 1;
    }
    /* The library linked is the one compiled against. */
    if (nradGetVersion() != NRAD_VERSION || (nradGetVersion() >> 22) != NRAD_VERSION_MAJOR) {
        fprintf(stderr, "version: linked %u, headers %u\n", (unsigned)nradGetVersion(), (unsigned)NRAD_VERSION);
        return 1;
    }
    /* The packed GPU buffer (328 bytes for the golden asset: tests/data/golden/tiny-gpu.bin). */
    {
        size_t gpuBytes = 0;
        uint32_t gpuWords[128];
        if (nradGetGpuBufferSize(asset, &gpuBytes) != NRAD_OK || gpuBytes != 328 ||
            nradPackGpuBuffer(asset, gpuWords, sizeof gpuWords) != NRAD_OK || gpuWords[0] != 0x5047524Eu) {
            fprintf(stderr, "GPU buffer: unexpected size %u or content\n", (unsigned)gpuBytes);
            return 1;
        }
    }
    printf("consumer ok: %u occupied voxels, kernel %d, radiance %g %g %g\n", info.occupiedVoxels, (int)nradActiveKernel(),
           rgb[0], rgb[1], rgb[2]);
    nradReleaseAsset(asset);
    return 0;
}
