#include "gpu/vulkan_compute.h"

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <stdexcept>

namespace nrad::gpu {
namespace {

void check(VkResult r, const char* call) {
    if (r != VK_SUCCESS) throw std::runtime_error(std::string(call) + " failed (VkResult " + std::to_string(int(r)) + ")");
}

std::vector<uint32_t> readSpirv(const std::string& path) {
    std::ifstream f(path, std::ios::binary | std::ios::ate);
    if (!f) throw std::runtime_error(path + ": cannot open SPIR-V file");
    const std::streamsize size = f.tellg();
    if (size <= 0 || size % 4 != 0) throw std::runtime_error(path + ": not a SPIR-V module (size)");
    std::vector<uint32_t> words(size_t(size) / 4);
    f.seekg(0);
    f.read(reinterpret_cast<char*>(words.data()), size);
    if (!f || words[0] != 0x07230203u) throw std::runtime_error(path + ": not a SPIR-V module (magic)");
    return words;
}

}  // namespace

std::unique_ptr<VulkanCompute> VulkanCompute::create(std::string& why) {
    std::unique_ptr<VulkanCompute> c(new VulkanCompute());
    VkApplicationInfo app{};
    app.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO;
    app.pApplicationName = "nrad-gpu-tests";
    app.apiVersion = VK_API_VERSION_1_0;
    VkInstanceCreateInfo ici{};
    ici.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
    ici.pApplicationInfo = &app;
    if (VkResult r = vkCreateInstance(&ici, nullptr, &c->instance_); r != VK_SUCCESS) {
        why = "vkCreateInstance failed (VkResult " + std::to_string(int(r)) + "): no Vulkan driver installed";
        c->instance_ = VK_NULL_HANDLE;
        return nullptr;
    }
    uint32_t count = 0;
    vkEnumeratePhysicalDevices(c->instance_, &count, nullptr);
    std::vector<VkPhysicalDevice> devices(count);
    if (count) vkEnumeratePhysicalDevices(c->instance_, &count, devices.data());
    const char* wanted = std::getenv("NRAD_VULKAN_DEVICE");
    for (VkPhysicalDevice d : devices) {
        VkPhysicalDeviceProperties props;
        vkGetPhysicalDeviceProperties(d, &props);
        if (wanted && *wanted && !std::strstr(props.deviceName, wanted)) continue;
        uint32_t nf = 0;
        vkGetPhysicalDeviceQueueFamilyProperties(d, &nf, nullptr);
        std::vector<VkQueueFamilyProperties> families(nf);
        vkGetPhysicalDeviceQueueFamilyProperties(d, &nf, families.data());
        for (uint32_t f = 0; f < nf; ++f)
            if (families[f].queueFlags & VK_QUEUE_COMPUTE_BIT) {
                c->physical_ = d;
                c->family_ = f;
                c->deviceName_ = props.deviceName;
                c->cpuDevice_ = props.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
                if (families[f].timestampValidBits > 0 && props.limits.timestampPeriod > 0.0f)
                    c->timestampPeriod_ = props.limits.timestampPeriod;
                break;
            }
        if (c->physical_) break;
    }
    if (!c->physical_) {
        why = count == 0 ? "the Vulkan loader found no physical device"
                         : "no Vulkan device with a compute queue" + std::string(wanted ? " matching NRAD_VULKAN_DEVICE" : "");
        return nullptr;
    }
    vkGetPhysicalDeviceMemoryProperties(c->physical_, &c->memory_);
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo qci{};
    qci.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
    qci.queueFamilyIndex = c->family_;
    qci.queueCount = 1;
    qci.pQueuePriorities = &priority;
    VkDeviceCreateInfo dci{};
    dci.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
    dci.queueCreateInfoCount = 1;
    dci.pQueueCreateInfos = &qci;
    check(vkCreateDevice(c->physical_, &dci, nullptr, &c->device_), "vkCreateDevice");
    vkGetDeviceQueue(c->device_, c->family_, 0, &c->queue_);
    VkCommandPoolCreateInfo pci{};
    pci.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
    pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pci.queueFamilyIndex = c->family_;
    check(vkCreateCommandPool(c->device_, &pci, nullptr, &c->pool_), "vkCreateCommandPool");
    if (c->timestampPeriod_ > 0.0f) {
        VkQueryPoolCreateInfo qpi{};
        qpi.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
        qpi.queryType = VK_QUERY_TYPE_TIMESTAMP;
        qpi.queryCount = 2;
        check(vkCreateQueryPool(c->device_, &qpi, nullptr, &c->queries_), "vkCreateQueryPool");
    }
    return c;
}

VulkanCompute::~VulkanCompute() {
    if (device_) {
        vkDeviceWaitIdle(device_);
        for (auto& p : pipelines_) {
            vkDestroyPipeline(device_, p->pipeline, nullptr);
            vkDestroyPipelineLayout(device_, p->layout, nullptr);
            vkDestroyDescriptorSetLayout(device_, p->setLayout, nullptr);
            vkDestroyShaderModule(device_, p->module, nullptr);
        }
        for (auto& b : buffers_) destroy(*b);
        if (queries_) vkDestroyQueryPool(device_, queries_, nullptr);
        if (pool_) vkDestroyCommandPool(device_, pool_, nullptr);
        vkDestroyDevice(device_, nullptr);
    }
    if (instance_) vkDestroyInstance(instance_, nullptr);
}

uint32_t VulkanCompute::memoryType(uint32_t bits, VkMemoryPropertyFlags want) const {
    for (uint32_t i = 0; i < memory_.memoryTypeCount; ++i)
        if ((bits & (1u << i)) && (memory_.memoryTypes[i].propertyFlags & want) == want) return i;
    throw std::runtime_error("no Vulkan memory type with the properties needed");
}

VulkanCompute::Buffer VulkanCompute::makeBuffer(size_t bytes, VkBufferUsageFlags usage, VkMemoryPropertyFlags props) {
    Buffer b;
    b.bytes = bytes < 4 ? 4 : (bytes + 3) / 4 * 4;
    VkBufferCreateInfo bci{};
    bci.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
    bci.size = b.bytes;
    bci.usage = usage;
    bci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    check(vkCreateBuffer(device_, &bci, nullptr, &b.buffer), "vkCreateBuffer");
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(device_, b.buffer, &req);
    VkMemoryAllocateInfo mai{};
    mai.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    mai.allocationSize = req.size;
    mai.memoryTypeIndex = memoryType(req.memoryTypeBits, props);
    check(vkAllocateMemory(device_, &mai, nullptr, &b.memory), "vkAllocateMemory");
    check(vkBindBufferMemory(device_, b.buffer, b.memory, 0), "vkBindBufferMemory");
    return b;
}

void VulkanCompute::destroy(Buffer& b) {
    if (b.buffer) vkDestroyBuffer(device_, b.buffer, nullptr);
    if (b.memory) vkFreeMemory(device_, b.memory, nullptr);
    b = Buffer();
}

VulkanCompute::Buffer* VulkanCompute::buffer(size_t bytes) {
    buffers_.push_back(std::make_unique<Buffer>(makeBuffer(
        bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
        VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT)));
    return buffers_.back().get();
}

VkCommandBuffer VulkanCompute::begin() {
    VkCommandBufferAllocateInfo cai{};
    cai.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
    cai.commandPool = pool_;
    cai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    cai.commandBufferCount = 1;
    VkCommandBuffer cb;
    check(vkAllocateCommandBuffers(device_, &cai, &cb), "vkAllocateCommandBuffers");
    VkCommandBufferBeginInfo bi{};
    bi.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    check(vkBeginCommandBuffer(cb, &bi), "vkBeginCommandBuffer");
    return cb;
}

void VulkanCompute::submitAndWait(VkCommandBuffer cb) {
    check(vkEndCommandBuffer(cb), "vkEndCommandBuffer");
    VkFenceCreateInfo fci{};
    fci.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
    VkFence fence;
    check(vkCreateFence(device_, &fci, nullptr, &fence), "vkCreateFence");
    VkSubmitInfo si{};
    si.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cb;
    VkResult r = vkQueueSubmit(queue_, 1, &si, fence);
    if (r == VK_SUCCESS) r = vkWaitForFences(device_, 1, &fence, VK_TRUE, UINT64_MAX);
    vkDestroyFence(device_, fence, nullptr);
    vkFreeCommandBuffers(device_, pool_, 1, &cb);
    check(r, "vkQueueSubmit / vkWaitForFences");
}

void VulkanCompute::copy(VkBuffer from, VkBuffer to, size_t bytes) {
    VkCommandBuffer cb = begin();
    VkBufferCopy region{0, 0, bytes};
    vkCmdCopyBuffer(cb, from, to, 1, &region);
    submitAndWait(cb);
}

void VulkanCompute::upload(Buffer* b, const void* data, size_t bytes) {
    if (bytes > b->bytes) throw std::runtime_error("upload larger than the buffer");
    Buffer staging = makeBuffer(bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
    void* mapped = nullptr;
    check(vkMapMemory(device_, staging.memory, 0, VK_WHOLE_SIZE, 0, &mapped), "vkMapMemory");
    std::memcpy(mapped, data, bytes);
    vkUnmapMemory(device_, staging.memory);
    copy(staging.buffer, b->buffer, bytes);
    destroy(staging);
}

void VulkanCompute::download(Buffer* b, void* data, size_t bytes) {
    if (bytes > b->bytes) throw std::runtime_error("download larger than the buffer");
    Buffer staging = makeBuffer(bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
    copy(b->buffer, staging.buffer, bytes);
    void* mapped = nullptr;
    check(vkMapMemory(device_, staging.memory, 0, VK_WHOLE_SIZE, 0, &mapped), "vkMapMemory");
    std::memcpy(data, mapped, bytes);
    vkUnmapMemory(device_, staging.memory);
    destroy(staging);
}

VulkanCompute::Pipeline* VulkanCompute::pipeline(const std::string& spirvPath, uint32_t bindings, uint32_t pushBytes) {
    auto p = std::make_unique<Pipeline>();
    p->bindings = bindings;
    p->pushBytes = pushBytes;
    const std::vector<uint32_t> code = readSpirv(spirvPath);
    VkShaderModuleCreateInfo smi{};
    smi.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
    smi.codeSize = code.size() * 4;
    smi.pCode = code.data();
    check(vkCreateShaderModule(device_, &smi, nullptr, &p->module), "vkCreateShaderModule");
    std::vector<VkDescriptorSetLayoutBinding> b(bindings);
    for (uint32_t i = 0; i < bindings; ++i) {
        b[i].binding = i;
        b[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        b[i].descriptorCount = 1;
        b[i].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
    }
    VkDescriptorSetLayoutCreateInfo dli{};
    dli.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
    dli.bindingCount = bindings;
    dli.pBindings = b.data();
    check(vkCreateDescriptorSetLayout(device_, &dli, nullptr, &p->setLayout), "vkCreateDescriptorSetLayout");
    VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, pushBytes};
    VkPipelineLayoutCreateInfo pli{};
    pli.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
    pli.setLayoutCount = 1;
    pli.pSetLayouts = &p->setLayout;
    pli.pushConstantRangeCount = pushBytes ? 1 : 0;
    pli.pPushConstantRanges = &range;
    check(vkCreatePipelineLayout(device_, &pli, nullptr, &p->layout), "vkCreatePipelineLayout");
    VkComputePipelineCreateInfo cpi{};
    cpi.sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO;
    cpi.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    cpi.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    cpi.stage.module = p->module;
    cpi.stage.pName = "main";
    cpi.layout = p->layout;
    check(vkCreateComputePipelines(device_, VK_NULL_HANDLE, 1, &cpi, nullptr, &p->pipeline), "vkCreateComputePipelines");
    pipelines_.push_back(std::move(p));
    return pipelines_.back().get();
}

double VulkanCompute::dispatch(Pipeline* p, const std::vector<Buffer*>& buffers, const void* push, uint32_t groups, int repeat) {
    if (buffers.size() != p->bindings) throw std::runtime_error("dispatch: wrong number of buffers");
    VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, p->bindings};
    VkDescriptorPoolCreateInfo dpi{};
    dpi.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
    dpi.maxSets = 1;
    dpi.poolSizeCount = 1;
    dpi.pPoolSizes = &size;
    VkDescriptorPool pool;
    check(vkCreateDescriptorPool(device_, &dpi, nullptr, &pool), "vkCreateDescriptorPool");
    VkDescriptorSetAllocateInfo dai{};
    dai.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
    dai.descriptorPool = pool;
    dai.descriptorSetCount = 1;
    dai.pSetLayouts = &p->setLayout;
    VkDescriptorSet set;
    check(vkAllocateDescriptorSets(device_, &dai, &set), "vkAllocateDescriptorSets");
    std::vector<VkDescriptorBufferInfo> infos(buffers.size());
    std::vector<VkWriteDescriptorSet> writes(buffers.size());
    for (size_t i = 0; i < buffers.size(); ++i) {
        infos[i] = {buffers[i]->buffer, 0, VK_WHOLE_SIZE};
        writes[i] = VkWriteDescriptorSet{};
        writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        writes[i].dstSet = set;
        writes[i].dstBinding = uint32_t(i);
        writes[i].descriptorCount = 1;
        writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        writes[i].pBufferInfo = &infos[i];
    }
    vkUpdateDescriptorSets(device_, uint32_t(writes.size()), writes.data(), 0, nullptr);

    VkCommandBuffer cb = begin();
    vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, p->pipeline);
    vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_COMPUTE, p->layout, 0, 1, &set, 0, nullptr);
    if (p->pushBytes) vkCmdPushConstants(cb, p->layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, p->pushBytes, push);
    writeTimestamp(cb, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    VkMemoryBarrier barrier{};
    barrier.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
    barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
    for (int r = 0; r < repeat; ++r) {
        if (r > 0)
            vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &barrier,
                                 0, nullptr, 0, nullptr);
        vkCmdDispatch(cb, groups, 1, 1);
    }
    writeTimestamp(cb, 1, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
    submitAndWait(cb);
    vkDestroyDescriptorPool(device_, pool, nullptr);
    const double ms = elapsedMs();
    return ms < 0.0 ? ms : ms / double(repeat > 0 ? repeat : 1);
}

void VulkanCompute::writeTimestamp(VkCommandBuffer cb, uint32_t index, VkPipelineStageFlagBits stage) {
    if (!queries_) return;
    if (index == 0) vkCmdResetQueryPool(cb, queries_, 0, 2);
    vkCmdWriteTimestamp(cb, stage, queries_, index);
}

double VulkanCompute::elapsedMs() {
    if (!queries_) return -1.0;
    uint64_t ticks[2] = {0, 0};
    check(vkGetQueryPoolResults(device_, queries_, 0, 2, sizeof ticks, ticks, sizeof(uint64_t),
                                VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
          "vkGetQueryPoolResults");
    return double(ticks[1] - ticks[0]) * double(timestampPeriod_) * 1e-6;
}

}  // namespace nrad::gpu
