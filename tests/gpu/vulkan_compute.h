// A minimal Vulkan compute harness for the GPU tests and benchmarks: one device (the first with a compute
// queue, or the one whose name contains NRAD_VULKAN_DEVICE), device-local storage buffers filled and read back
// through staging copies, compute pipelines from SPIR-V files, dispatches timed with GPU timestamps.
// Plain Vulkan 1.0, no extensions; every failure throws std::runtime_error naming the call.
#pragma once

#include <vulkan/vulkan.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace nrad::gpu {

class VulkanCompute {
public:
    // The context, or null with `why` set when this machine has no Vulkan loader or device.
    static std::unique_ptr<VulkanCompute> create(std::string& why);
    ~VulkanCompute();
    VulkanCompute(const VulkanCompute&) = delete;
    VulkanCompute& operator=(const VulkanCompute&) = delete;

    struct Buffer {
        VkBuffer buffer = VK_NULL_HANDLE;
        VkDeviceMemory memory = VK_NULL_HANDLE;
        size_t bytes = 0;
    };
    // A device-local storage buffer of at least `bytes` (4 at least), released with the context.
    Buffer* buffer(size_t bytes);
    void upload(Buffer* b, const void* data, size_t bytes);
    void download(Buffer* b, void* data, size_t bytes);

    struct Pipeline {
        VkShaderModule module = VK_NULL_HANDLE;
        VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
        VkPipelineLayout layout = VK_NULL_HANDLE;
        VkPipeline pipeline = VK_NULL_HANDLE;
        uint32_t bindings = 0, pushBytes = 0;
    };
    // A compute pipeline from a SPIR-V file whose set 0 has `bindings` storage buffers (0, 1, ...).
    Pipeline* pipeline(const std::string& spirvPath, uint32_t bindings, uint32_t pushBytes);

    // Binds `buffers` to set 0 in order, pushes the constants, dispatches `groups` x 1 x 1 workgroups
    // `repeat` times in one command buffer and waits. Returns the GPU time of one dispatch in milliseconds
    // (the mean, from timestamps), or a negative value where the queue has no timestamps.
    double dispatch(Pipeline* p, const std::vector<Buffer*>& buffers, const void* push, uint32_t groups, int repeat = 1);

    const std::string& deviceName() const { return deviceName_; }
    bool isCpuDevice() const { return cpuDevice_; }

    // For work beyond compute (the raster example): the device, a memory type with `want` among `bits`, a
    // one-time command buffer and its submission (waits), and the two timestamps of the query pool (write
    // index 0 and 1 into `cb`; elapsedMs reads them; negative where the queue has no timestamps).
    VkDevice device() const { return device_; }
    uint32_t memoryType(uint32_t bits, VkMemoryPropertyFlags want) const;
    VkCommandBuffer begin();
    void submitAndWait(VkCommandBuffer cb);
    void writeTimestamp(VkCommandBuffer cb, uint32_t index, VkPipelineStageFlagBits stage);
    double elapsedMs();

private:
    VulkanCompute() = default;
    Buffer makeBuffer(size_t bytes, VkBufferUsageFlags usage, VkMemoryPropertyFlags props);
    void destroy(Buffer& b);
    void copy(VkBuffer from, VkBuffer to, size_t bytes);

    VkInstance instance_ = VK_NULL_HANDLE;
    VkPhysicalDevice physical_ = VK_NULL_HANDLE;
    VkDevice device_ = VK_NULL_HANDLE;
    VkQueue queue_ = VK_NULL_HANDLE;
    uint32_t family_ = 0;
    VkCommandPool pool_ = VK_NULL_HANDLE;
    VkQueryPool queries_ = VK_NULL_HANDLE;
    VkPhysicalDeviceMemoryProperties memory_{};
    float timestampPeriod_ = 0.0f;  // ns per tick; 0: no timestamps
    std::string deviceName_;
    bool cpuDevice_ = false;
    std::vector<std::unique_ptr<Buffer>> buffers_;
    std::vector<std::unique_ptr<Pipeline>> pipelines_;
};

}  // namespace nrad::gpu
