// An engine's use of nrad on the GPU, end to end, in plain Vulkan 1.0: rasterise a glTF scene into a G-buffer
// (position, shading normal, material terms), shade every pixel in a compute pass with the asset through
// runtime/shaders/nrad.glsl, and write the image. It checks itself against the CPU runtime (nradShadeBatch on
// the very G-buffer it rasterised) and prints the shading pass's GPU time against the CPU runtime's.
//
//   nrad_vulkan_example SCENE.gltf ASSET.nrad OUT.png|OUT.exr [--width W] [--height H] [--repeat N]
//       [--insert OBJECT.gltf@x,y,z]...  (objects that were not in the bake, moved there: a moving object, shaded
//       with the asset's volume query, nradShadeVolume; the asset must be baked with --volume-points)
//
// Exit status: 0 when the GPU image agrees with the CPU runtime within docs/runtime.md's tolerance, 1 when it
// does not, 2 for bad arguments or input, 3 when no Vulkan device exists. The scene is read with the baker's
// loader (an engine has its own); textures are not sampled here (the bundled scenes have none): an engine
// writes its textured material terms into the same G-buffer.
#include <nrad/nrad.h>
#include <nrad/nrad.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "baker/render/image_io.h"
#include "baker/render/surface.h"
#include "baker/scene/gltf_loader.h"
#include "gpu/gbuffer.h"
#include "gpu/vulkan_compute.h"

namespace {

using nrad::gpu::VulkanCompute;

void check(VkResult r, const char* call) {
    if (r != VK_SUCCESS) throw std::runtime_error(std::string(call) + " failed (VkResult " + std::to_string(int(r)) + ")");
}

std::vector<uint32_t> readSpirv(const std::string& path) {
    FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) throw std::runtime_error(path + ": cannot open SPIR-V file");
    std::vector<uint32_t> words;
    uint32_t w;
    while (std::fread(&w, 4, 1, f) == 1) words.push_back(w);
    std::fclose(f);
    return words;
}

struct Vertex {
    float position[4], normal[4];
};
struct Triangle {
    float geometricNormal[4], baseColorMetallic[4], emissionFrontRoughness[4], emissionBackSpecular[4];
};
struct View {
    glm::mat4 clipFromWorld;
    glm::vec4 eye;  // xyz, w = 1: perspective; w = 0: orthographic, xyz the viewing direction
};

// The camera's projection, matching the baker's CameraRays at pixel centres (Vulkan's y axis points down).
View viewOf(const nrad::Camera& cam, const nrad::Bounds3& bounds, int width, int height) {
    const glm::mat3 r = glm::transpose(cam.worldFromCamera);
    glm::mat4 v(1.0f);
    for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k) v[c][k] = r[c][k];
    v[3] = glm::vec4(-(r * cam.position), 1.0f);
    float far = 0.0f;
    for (int i = 0; i < 8; ++i) {
        glm::vec3 corner((i & 1) ? bounds.upper.x : bounds.lower.x, (i & 2) ? bounds.upper.y : bounds.lower.y,
                         (i & 4) ? bounds.upper.z : bounds.lower.z);
        far = std::max(far, glm::length(corner - cam.position));
    }
    far = 1.5f * far + 1e-6f;
    const float aspect = float(width) / float(height);
    glm::mat4 p(0.0f);
    View out;
    if (cam.type == nrad::Camera::Type::Perspective) {
        // Reversed depth with an infinite far plane (depth = near / distance, nearer is greater): float depth
        // then resolves distances relatively, so an emitter 0.1 mm in front of a ceiling still wins.
        const float halfH = std::tan(0.5f * cam.yfov), halfW = halfH * aspect, near = far * 1e-6f;
        p[0][0] = 1.0f / halfW;
        p[1][1] = -1.0f / halfH;
        p[3][2] = near;
        p[2][3] = -1.0f;
        out.eye = glm::vec4(cam.position, 1.0f);
    } else {
        const float halfH = cam.ymag, halfW = halfH * aspect;
        p[0][0] = 1.0f / halfW;
        p[1][1] = -1.0f / halfH;
        p[2][2] = 1.0f / far;  // reversed: depth 1 + z_camera / far, nearer is greater
        p[3][2] = 1.0f;
        p[3][3] = 1.0f;
        out.eye = glm::vec4(-cam.worldFromCamera[2], 0.0f);
    }
    out.clipFromWorld = p * v;
    return out;
}

struct Image {
    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;
};

class Example {
public:
    Example(VulkanCompute& vk, int width, int height) : vk_(vk), dev_(vk.device()), width_(width), height_(height) {}
    ~Example() {
        vkDeviceWaitIdle(dev_);
        for (VkPipeline p : pipelines_) vkDestroyPipeline(dev_, p, nullptr);
        for (VkPipelineLayout l : layouts_) vkDestroyPipelineLayout(dev_, l, nullptr);
        for (VkDescriptorSetLayout l : setLayouts_) vkDestroyDescriptorSetLayout(dev_, l, nullptr);
        for (VkShaderModule m : modules_) vkDestroyShaderModule(dev_, m, nullptr);
        if (pool_) vkDestroyDescriptorPool(dev_, pool_, nullptr);
        if (framebuffer_) vkDestroyFramebuffer(dev_, framebuffer_, nullptr);
        if (renderPass_) vkDestroyRenderPass(dev_, renderPass_, nullptr);
        for (Image& i : images_) {
            vkDestroyImageView(dev_, i.view, nullptr);
            vkDestroyImage(dev_, i.image, nullptr);
            vkFreeMemory(dev_, i.memory, nullptr);
        }
    }

    Image& image(VkFormat format, VkImageUsageFlags usage, VkImageAspectFlags aspect) {
        Image im;
        VkImageCreateInfo ici{};
        ici.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
        ici.imageType = VK_IMAGE_TYPE_2D;
        ici.format = format;
        ici.extent = {uint32_t(width_), uint32_t(height_), 1};
        ici.mipLevels = 1;
        ici.arrayLayers = 1;
        ici.samples = VK_SAMPLE_COUNT_1_BIT;
        ici.tiling = VK_IMAGE_TILING_OPTIMAL;
        ici.usage = usage;
        ici.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
        check(vkCreateImage(dev_, &ici, nullptr, &im.image), "vkCreateImage");
        VkMemoryRequirements req;
        vkGetImageMemoryRequirements(dev_, im.image, &req);
        VkMemoryAllocateInfo mai{};
        mai.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
        mai.allocationSize = req.size;
        mai.memoryTypeIndex = vk_.memoryType(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
        check(vkAllocateMemory(dev_, &mai, nullptr, &im.memory), "vkAllocateMemory");
        check(vkBindImageMemory(dev_, im.image, im.memory, 0), "vkBindImageMemory");
        VkImageViewCreateInfo vci{};
        vci.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
        vci.image = im.image;
        vci.viewType = VK_IMAGE_VIEW_TYPE_2D;
        vci.format = format;
        vci.subresourceRange = {aspect, 0, 1, 0, 1};
        check(vkCreateImageView(dev_, &vci, nullptr, &im.view), "vkCreateImageView");
        images_.push_back(im);
        return images_.back();
    }

    VkShaderModule module(const std::string& path) {
        const std::vector<uint32_t> code = readSpirv(path);
        VkShaderModuleCreateInfo smi{};
        smi.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
        smi.codeSize = code.size() * 4;
        smi.pCode = code.data();
        VkShaderModule m;
        check(vkCreateShaderModule(dev_, &smi, nullptr, &m), "vkCreateShaderModule");
        modules_.push_back(m);
        return m;
    }

    // A set layout of `types` at bindings 0, 1, ... and a pipeline layout with it and the View push constants.
    VkPipelineLayout layout(const std::vector<VkDescriptorType>& types, VkShaderStageFlags stages, VkDescriptorSetLayout& set) {
        std::vector<VkDescriptorSetLayoutBinding> b(types.size());
        for (size_t i = 0; i < types.size(); ++i) b[i] = {uint32_t(i), types[i], 1, stages, nullptr};
        VkDescriptorSetLayoutCreateInfo dli{};
        dli.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
        dli.bindingCount = uint32_t(b.size());
        dli.pBindings = b.data();
        check(vkCreateDescriptorSetLayout(dev_, &dli, nullptr, &set), "vkCreateDescriptorSetLayout");
        setLayouts_.push_back(set);
        VkPushConstantRange range{stages, 0, sizeof(View)};
        VkPipelineLayoutCreateInfo pli{};
        pli.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
        pli.setLayoutCount = 1;
        pli.pSetLayouts = &set;
        pli.pushConstantRangeCount = 1;
        pli.pPushConstantRanges = &range;
        VkPipelineLayout l;
        check(vkCreatePipelineLayout(dev_, &pli, nullptr, &l), "vkCreatePipelineLayout");
        layouts_.push_back(l);
        return l;
    }

    VkDescriptorSet descriptorSet(VkDescriptorSetLayout layout) {
        if (!pool_) {
            VkDescriptorPoolSize sizes[2] = {{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 8}, {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 8}};
            VkDescriptorPoolCreateInfo dpi{};
            dpi.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
            dpi.maxSets = 4;
            dpi.poolSizeCount = 2;
            dpi.pPoolSizes = sizes;
            check(vkCreateDescriptorPool(dev_, &dpi, nullptr, &pool_), "vkCreateDescriptorPool");
        }
        VkDescriptorSetAllocateInfo dai{};
        dai.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
        dai.descriptorPool = pool_;
        dai.descriptorSetCount = 1;
        dai.pSetLayouts = &layout;
        VkDescriptorSet set;
        check(vkAllocateDescriptorSets(dev_, &dai, &set), "vkAllocateDescriptorSets");
        return set;
    }

    void bindBuffer(VkDescriptorSet set, uint32_t binding, VkBuffer buffer) {
        const VkDescriptorBufferInfo info{buffer, 0, VK_WHOLE_SIZE};
        write(set, binding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, &info, nullptr);
    }
    void bindImage(VkDescriptorSet set, uint32_t binding, VkImageView view) {
        const VkDescriptorImageInfo info{VK_NULL_HANDLE, view, VK_IMAGE_LAYOUT_GENERAL};
        write(set, binding, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, nullptr, &info);
    }

    // Four RGBA32F colour targets (left in GENERAL for the compute pass and the copies) and a depth buffer.
    VkRenderPass renderPass(const Image (&targets)[4], const Image& depth) {
        VkAttachmentDescription a[5]{};
        VkAttachmentReference refs[4];
        for (int i = 0; i < 5; ++i) {
            a[i].format = i < 4 ? VK_FORMAT_R32G32B32A32_SFLOAT : VK_FORMAT_D32_SFLOAT;
            a[i].samples = VK_SAMPLE_COUNT_1_BIT;
            a[i].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
            a[i].storeOp = i < 4 ? VK_ATTACHMENT_STORE_OP_STORE : VK_ATTACHMENT_STORE_OP_DONT_CARE;
            a[i].stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
            a[i].stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
            a[i].initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
            a[i].finalLayout = i < 4 ? VK_IMAGE_LAYOUT_GENERAL : VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
            if (i < 4) refs[i] = {uint32_t(i), VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
        }
        VkAttachmentReference depthRef{4, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
        VkSubpassDescription sub{};
        sub.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
        sub.colorAttachmentCount = 4;
        sub.pColorAttachments = refs;
        sub.pDepthStencilAttachment = &depthRef;
        VkSubpassDependency dep{};  // the G-buffer's writes before the compute pass and the copies read it
        dep.srcSubpass = 0;
        dep.dstSubpass = VK_SUBPASS_EXTERNAL;
        dep.srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
        dep.dstStageMask = VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT;
        dep.srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
        dep.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT;
        VkRenderPassCreateInfo rpi{};
        rpi.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO;
        rpi.attachmentCount = 5;
        rpi.pAttachments = a;
        rpi.subpassCount = 1;
        rpi.pSubpasses = &sub;
        rpi.dependencyCount = 1;
        rpi.pDependencies = &dep;
        check(vkCreateRenderPass(dev_, &rpi, nullptr, &renderPass_), "vkCreateRenderPass");
        VkImageView views[5] = {targets[0].view, targets[1].view, targets[2].view, targets[3].view, depth.view};
        VkFramebufferCreateInfo fci{};
        fci.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO;
        fci.renderPass = renderPass_;
        fci.attachmentCount = 5;
        fci.pAttachments = views;
        fci.width = uint32_t(width_);
        fci.height = uint32_t(height_);
        fci.layers = 1;
        check(vkCreateFramebuffer(dev_, &fci, nullptr, &framebuffer_), "vkCreateFramebuffer");
        return renderPass_;
    }

    VkPipeline graphicsPipeline(VkShaderModule vert, VkShaderModule frag, VkPipelineLayout layout) {
        VkPipelineShaderStageCreateInfo stages[2]{};
        for (int i = 0; i < 2; ++i) {
            stages[i].sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
            stages[i].stage = i == 0 ? VK_SHADER_STAGE_VERTEX_BIT : VK_SHADER_STAGE_FRAGMENT_BIT;
            stages[i].module = i == 0 ? vert : frag;
            stages[i].pName = "main";
        }
        VkPipelineVertexInputStateCreateInfo vin{};
        vin.sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO;
        VkPipelineInputAssemblyStateCreateInfo ia{};
        ia.sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO;
        ia.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
        VkViewport viewport{0.0f, 0.0f, float(width_), float(height_), 0.0f, 1.0f};
        VkRect2D scissor{{0, 0}, {uint32_t(width_), uint32_t(height_)}};
        VkPipelineViewportStateCreateInfo vp{};
        vp.sType = VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO;
        vp.viewportCount = 1;
        vp.pViewports = &viewport;
        vp.scissorCount = 1;
        vp.pScissors = &scissor;
        VkPipelineRasterizationStateCreateInfo rs{};
        rs.sType = VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO;
        rs.polygonMode = VK_POLYGON_MODE_FILL;
        rs.cullMode = VK_CULL_MODE_NONE;
        rs.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
        rs.lineWidth = 1.0f;
        VkPipelineMultisampleStateCreateInfo ms{};
        ms.sType = VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO;
        ms.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
        VkPipelineDepthStencilStateCreateInfo ds{};
        ds.sType = VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO;
        ds.depthTestEnable = VK_TRUE;
        ds.depthWriteEnable = VK_TRUE;
        ds.depthCompareOp = VK_COMPARE_OP_GREATER;  // reversed depth
        VkPipelineColorBlendAttachmentState blend[4]{};
        for (auto& b : blend)
            b.colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT | VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
        VkPipelineColorBlendStateCreateInfo cb{};
        cb.sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO;
        cb.attachmentCount = 4;
        cb.pAttachments = blend;
        VkGraphicsPipelineCreateInfo gpi{};
        gpi.sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO;
        gpi.stageCount = 2;
        gpi.pStages = stages;
        gpi.pVertexInputState = &vin;
        gpi.pInputAssemblyState = &ia;
        gpi.pViewportState = &vp;
        gpi.pRasterizationState = &rs;
        gpi.pMultisampleState = &ms;
        gpi.pDepthStencilState = &ds;
        gpi.pColorBlendState = &cb;
        gpi.layout = layout;
        gpi.renderPass = renderPass_;
        VkPipeline p;
        check(vkCreateGraphicsPipelines(dev_, VK_NULL_HANDLE, 1, &gpi, nullptr, &p), "vkCreateGraphicsPipelines");
        pipelines_.push_back(p);
        return p;
    }

    VkPipeline computePipeline(VkShaderModule comp, VkPipelineLayout layout) {
        VkComputePipelineCreateInfo cpi{};
        cpi.sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO;
        cpi.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
        cpi.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
        cpi.stage.module = comp;
        cpi.stage.pName = "main";
        cpi.layout = layout;
        VkPipeline p;
        check(vkCreateComputePipelines(dev_, VK_NULL_HANDLE, 1, &cpi, nullptr, &p), "vkCreateComputePipelines");
        pipelines_.push_back(p);
        return p;
    }

    VkFramebuffer framebuffer() const { return framebuffer_; }

private:
    void write(VkDescriptorSet set, uint32_t binding, VkDescriptorType type, const VkDescriptorBufferInfo* buffer,
               const VkDescriptorImageInfo* image) {
        VkWriteDescriptorSet w{};
        w.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        w.dstSet = set;
        w.dstBinding = binding;
        w.descriptorCount = 1;
        w.descriptorType = type;
        w.pBufferInfo = buffer;
        w.pImageInfo = image;
        vkUpdateDescriptorSets(dev_, 1, &w, 0, nullptr);
    }

    VulkanCompute& vk_;
    VkDevice dev_;
    int width_, height_;
    std::vector<Image> images_;
    std::vector<VkShaderModule> modules_;
    std::vector<VkDescriptorSetLayout> setLayouts_;
    std::vector<VkPipelineLayout> layouts_;
    std::vector<VkPipeline> pipelines_;
    VkDescriptorPool pool_ = VK_NULL_HANDLE;
    VkRenderPass renderPass_ = VK_NULL_HANDLE;
    VkFramebuffer framebuffer_ = VK_NULL_HANDLE;
};

void copyImageToBuffer(VkCommandBuffer cb, const Image& im, VulkanCompute::Buffer* b, int width, int height) {
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {uint32_t(width), uint32_t(height), 1};
    vkCmdCopyImageToBuffer(cb, im.image, VK_IMAGE_LAYOUT_GENERAL, b->buffer, 1, &region);
}

int run(int argc, char** argv) {
    if (argc < 4) {
        std::fprintf(stderr, "usage: %s SCENE.gltf ASSET.nrad OUT.png|OUT.exr [--width W] [--height H] [--repeat N] "
                             "[--insert OBJECT.gltf@x,y,z]...\n", argv[0]);
        return 2;
    }
    int width = 512, height = 0, repeat = 5;
    std::vector<std::pair<std::string, glm::vec3>> inserts;
    for (int i = 4; i + 1 < argc; i += 2) {
        const std::string flag = argv[i];
        if (flag == "--insert") {  // FILE@x,y,z
            const std::string spec = argv[i + 1];
            const size_t at = spec.rfind('@');
            glm::vec3 o(0.0f);
            char rest;
            if (at == std::string::npos || std::sscanf(spec.c_str() + at + 1, "%f,%f,%f%c", &o.x, &o.y, &o.z, &rest) != 3) {
                std::fprintf(stderr, "%s: --insert %s: expected FILE.gltf@x,y,z\n", argv[0], spec.c_str());
                return 2;
            }
            inserts.push_back({spec.substr(0, at), o});
            continue;
        }
        const int value = std::atoi(argv[i + 1]);
        if (value <= 0 || value > 16384 || (flag != "--width" && flag != "--height" && flag != "--repeat")) {
            std::fprintf(stderr, "%s: bad option %s %s\n", argv[0], argv[i], argv[i + 1]);
            return 2;
        }
        (flag == "--width" ? width : flag == "--height" ? height : repeat) = value;
    }
    if (!nrad::isSupportedImagePath(argv[3])) {
        std::fprintf(stderr, "%s: %s: the output must be .png or .exr\n", argv[0], argv[3]);
        return 2;
    }
    nrad::Scene scene = nrad::loadGltf(argv[1]);
    const nrad::Camera camera = nrad::defaultCamera(scene);
    for (const auto& [file, offset] : inserts) nrad::insertObject(scene, nrad::loadGltf(file), offset, file);
    if (height == 0) height = std::max(1, int(std::lround(width / (camera.aspectRatio > 0.0f ? camera.aspectRatio : 1.0f))));
    nrad::Asset asset;
    std::string message;
    if (NradStatus st = asset.loadFromFile(argv[2], &message); st != NRAD_OK) {
        std::fprintf(stderr, "%s: %s\n", argv[0], message.c_str());
        return 2;
    }
    size_t assetBytes = 0;
    if (NradStatus st = asset.gpuBufferSize(assetBytes); st != NRAD_OK) {
        std::fprintf(stderr, "%s: %s: %s\n", argv[0], argv[2], nradStatusString(st));
        return 2;
    }
    std::vector<uint32_t> packed(assetBytes / 4);
    asset.packGpuBuffer(packed.data(), assetBytes);

    std::string why;
    std::unique_ptr<VulkanCompute> vk = VulkanCompute::create(why);
    if (!vk) {
        std::fprintf(stderr, "%s: %s\n", argv[0], why.c_str());
        return 3;
    }

    // The scene as an engine would upload it: unindexed vertices, per-triangle material terms.
    const nrad::TriangleMesh& mesh = scene.mesh;
    std::vector<Vertex> vertices;
    std::vector<Triangle> triangles;
    for (uint32_t t = 0; t < mesh.triangleCount(); ++t) {
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = mesh.triangles[t][k];
            vertices.push_back({{mesh.positions[v].x, mesh.positions[v].y, mesh.positions[v].z, 1.0f},
                                {mesh.normals[v].x, mesh.normals[v].y, mesh.normals[v].z, 0.0f}});
        }
        const nrad::Material& m = scene.materials[mesh.materialIds[t]];
        const glm::vec3 ng = mesh.geometricNormal(t), base = glm::clamp(m.baseColor, 0.0f, 1.0f);
        const glm::vec3 front = nrad::emittedRadiance(scene, t, 1.0f / 3.0f, 1.0f / 3.0f, true);
        const glm::vec3 back = nrad::emittedRadiance(scene, t, 1.0f / 3.0f, 1.0f / 3.0f, false);
        // w: 1 for an inserted object's triangle (the G-buffer marks its pixels: position w = 2)
        triangles.push_back({{ng.x, ng.y, ng.z, scene.insertedObject(t) >= 0 ? 1.0f : 0.0f},
                             {base.x, base.y, base.z, std::clamp(m.metallic, 0.0f, 1.0f)},
                             {front.x, front.y, front.z, std::clamp(m.roughness, 0.0f, 1.0f)},
                             {back.x, back.y, back.z, m.specular}});
    }
    const View view = viewOf(camera, scene.bounds, width, height);

    Example ex(*vk, width, height);
    const VkImageUsageFlags targetUsage =
        VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
    const Image targets[4] = {ex.image(VK_FORMAT_R32G32B32A32_SFLOAT, targetUsage, VK_IMAGE_ASPECT_COLOR_BIT),
                              ex.image(VK_FORMAT_R32G32B32A32_SFLOAT, targetUsage, VK_IMAGE_ASPECT_COLOR_BIT),
                              ex.image(VK_FORMAT_R32G32B32A32_SFLOAT, targetUsage, VK_IMAGE_ASPECT_COLOR_BIT),
                              ex.image(VK_FORMAT_R32G32B32A32_SFLOAT, targetUsage, VK_IMAGE_ASPECT_COLOR_BIT)};
    const Image depth = ex.image(VK_FORMAT_D32_SFLOAT, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT, VK_IMAGE_ASPECT_DEPTH_BIT);
    const Image shaded = ex.image(VK_FORMAT_R32G32B32A32_SFLOAT, VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                                  VK_IMAGE_ASPECT_COLOR_BIT);
    const VkRenderPass renderPass = ex.renderPass(targets, depth);

    VulkanCompute::Buffer* vertexBuffer = vk->buffer(vertices.size() * sizeof(Vertex));
    VulkanCompute::Buffer* triangleBuffer = vk->buffer(triangles.size() * sizeof(Triangle));
    VulkanCompute::Buffer* assetBuffer = vk->buffer(assetBytes);
    vk->upload(vertexBuffer, vertices.data(), vertices.size() * sizeof(Vertex));
    vk->upload(triangleBuffer, triangles.data(), triangles.size() * sizeof(Triangle));
    vk->upload(assetBuffer, packed.data(), assetBytes);

    const std::string dir = NRAD_EXAMPLE_SPV_DIR;
    VkDescriptorSetLayout rasterSetLayout, shadeSetLayout;
    const VkPipelineLayout rasterLayout = ex.layout({VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                                    VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, rasterSetLayout);
    const VkPipelineLayout shadeLayout =
        ex.layout({VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE,
                   VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
                  VK_SHADER_STAGE_COMPUTE_BIT, shadeSetLayout);
    const VkPipeline raster = ex.graphicsPipeline(ex.module(dir + "/gbuffer.vert.spv"), ex.module(dir + "/gbuffer.frag.spv"), rasterLayout);
    const VkPipeline shade = ex.computePipeline(ex.module(dir + "/shade.comp.spv"), shadeLayout);
    const VkDescriptorSet rasterSet = ex.descriptorSet(rasterSetLayout), shadeSet = ex.descriptorSet(shadeSetLayout);
    ex.bindBuffer(rasterSet, 0, vertexBuffer->buffer);
    ex.bindBuffer(rasterSet, 1, triangleBuffer->buffer);
    ex.bindBuffer(shadeSet, 0, assetBuffer->buffer);
    for (uint32_t i = 0; i < 4; ++i) ex.bindImage(shadeSet, 1 + i, targets[i].view);
    ex.bindImage(shadeSet, 5, shaded.view);

    // 1. The G-buffer pass, and the output image made ready for the compute pass.
    VkCommandBuffer cb = vk->begin();
    VkClearValue clears[5] = {};
    clears[4].depthStencil = {0.0f, 0};  // reversed depth: 0 is infinitely far
    VkRenderPassBeginInfo rbi{};
    rbi.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO;
    rbi.renderPass = renderPass;
    rbi.framebuffer = ex.framebuffer();
    rbi.renderArea = {{0, 0}, {uint32_t(width), uint32_t(height)}};
    rbi.clearValueCount = 5;
    rbi.pClearValues = clears;
    vkCmdBeginRenderPass(cb, &rbi, VK_SUBPASS_CONTENTS_INLINE);
    vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_GRAPHICS, raster);
    vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_GRAPHICS, rasterLayout, 0, 1, &rasterSet, 0, nullptr);
    vkCmdPushConstants(cb, rasterLayout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(View), &view);
    vkCmdDraw(cb, uint32_t(vertices.size()), 1, 0, 0);
    vkCmdEndRenderPass(cb);
    VkImageMemoryBarrier toGeneral{};
    toGeneral.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
    toGeneral.dstAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    toGeneral.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    toGeneral.newLayout = VK_IMAGE_LAYOUT_GENERAL;
    toGeneral.srcQueueFamilyIndex = toGeneral.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    toGeneral.image = shaded.image;
    toGeneral.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 0, nullptr, 0, nullptr, 1,
                         &toGeneral);
    vk->submitAndWait(cb);

    // 2. The shading pass, `repeat` times, timed on the GPU.
    cb = vk->begin();
    vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, shade);
    vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_COMPUTE, shadeLayout, 0, 1, &shadeSet, 0, nullptr);
    vkCmdPushConstants(cb, shadeLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(View), &view);
    vk->writeTimestamp(cb, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    for (int r = 0; r < repeat; ++r) vkCmdDispatch(cb, uint32_t((width + 7) / 8), uint32_t((height + 7) / 8), 1);
    vk->writeTimestamp(cb, 1, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
    const auto wall0 = std::chrono::steady_clock::now();
    vk->submitAndWait(cb);
    const double wallMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wall0).count() / repeat;
    const double gpuMs = vk->elapsedMs() / repeat;

    // 3. Read back the image and the G-buffer.
    const size_t pixels = size_t(width) * size_t(height), bytes = pixels * 16;
    std::vector<VulkanCompute::Buffer*> readback;
    for (int i = 0; i < 5; ++i) readback.push_back(vk->buffer(bytes));
    cb = vk->begin();
    VkMemoryBarrier written{};
    written.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
    written.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    written.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &written, 0, nullptr, 0, nullptr);
    for (int i = 0; i < 4; ++i) copyImageToBuffer(cb, targets[i], readback[size_t(i)], width, height);
    copyImageToBuffer(cb, shaded, readback[4], width, height);
    vk->submitAndWait(cb);
    std::vector<float> g[5];
    for (int i = 0; i < 5; ++i) {
        g[i].resize(pixels * 4);
        vk->download(readback[size_t(i)], g[i].data(), bytes);
    }

    // 4. The CPU runtime on the same G-buffer: the image must agree (docs/runtime.md's tolerance). The baked
    // surfaces through nradShadeBatch, the inserted objects' pixels (position w 2) through nradShadeGBuffer's volume
    // query.
    std::vector<float> p, n, d, rgb;
    std::vector<NradSurface> surfaces;
    std::vector<size_t> pixelOf;
    std::vector<uint8_t> moving;
    for (size_t i = 0; i < pixels; ++i) {
        if (g[0][4 * i + 3] == 0.0f) continue;
        const glm::vec3 pos(g[0][4 * i], g[0][4 * i + 1], g[0][4 * i + 2]);
        const glm::vec3 wo = view.eye.w != 0.0f ? glm::normalize(glm::vec3(view.eye) - pos) : -glm::vec3(view.eye);
        for (int k = 0; k < 3; ++k) {
            p.push_back(pos[k]);
            n.push_back(g[1][4 * i + size_t(k)]);
            d.push_back(wo[k]);
        }
        surfaces.push_back({{g[2][4 * i], g[2][4 * i + 1], g[2][4 * i + 2]}, g[2][4 * i + 3], g[1][4 * i + 3], g[3][4 * i + 3],
                            {g[3][4 * i], g[3][4 * i + 1], g[3][4 * i + 2]}});
        pixelOf.push_back(i);
        moving.push_back(g[0][4 * i + 3] > 1.5f);
    }
    rgb.resize(p.size());
    const auto cpu0 = std::chrono::steady_clock::now();
    asset.shadeBatch(surfaces.size(), p.data(), n.data(), d.data(), surfaces.data(), rgb.data());
    const double cpuMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - cpu0).count();
    size_t movingPixels = 0;
    for (size_t e = 0; e < pixelOf.size(); ++e) {
        if (!moving[e]) continue;
        ++movingPixels;
        NradGBuffer one;
        std::memset(&one, 0, sizeof one);
        one.structSize = sizeof(NradGBuffer);
        one.flags = NRAD_GBUFFER_VOLUME | NRAD_GBUFFER_UNIT_VECTORS;
        one.count = 1;
        one.position = {&p[3 * e], 0, NRAD_FORMAT_F32};
        one.normal = {&n[3 * e], 0, NRAD_FORMAT_F32};
        one.direction = {&d[3 * e], 0, NRAD_FORMAT_F32};
        one.surfaces = &surfaces[e];
        one.output = &rgb[3 * e];
        one.outputFormat = NRAD_FORMAT_F32;
        one.outputChannels = 3;
        if (NradStatus st = nradShadeGBuffer(asset.get(), &one, nullptr, 0); st != NRAD_OK) {
            std::fprintf(stderr, "%s: %s: the volume query: %s (bake the asset with --volume-points)\n", argv[0], argv[2],
                         nradStatusString(st));
            return 2;
        }
    }
    float largest = 0.0f;
    for (float v : rgb) largest = std::max(largest, std::abs(v));
    double worst = 0.0;
    size_t nonFinite = 0;
    for (size_t e = 0; e < pixelOf.size(); ++e)
        for (int c = 0; c < 3; ++c) {
            const double gpu = g[4][4 * pixelOf[e] + size_t(c)], cpu = rgb[3 * e + size_t(c)];
            if (!std::isfinite(gpu)) ++nonFinite;
            worst = std::max(worst, std::abs(gpu - cpu) / std::max(std::abs(cpu), 1e-3 * double(largest) + 1e-30));
        }

    nrad::Image image(width, height);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const size_t i = size_t(y) * size_t(width) + size_t(x);
            image.at(x, y) = glm::vec3(g[4][4 * i], g[4][4 * i + 1], g[4][4 * i + 2]);
        }
    nrad::writeImage(argv[3], image);

    std::printf("device: %s\n", vk->deviceName().c_str());
    std::printf("image: %d x %d, %zu shaded pixels (%zu of inserted objects, through the volume query), written to %s\n", width,
                height, pixelOf.size(), movingPixels, argv[3]);
    std::printf("shading pass: %.3f ms on the GPU (timestamps; %.3f ms wall per pass, mean of %d); CPU runtime "
                "nradShadeBatch on one thread: %.3f ms (%.1fx the GPU pass)\n",
                gpuMs, wallMs, repeat, cpuMs, cpuMs / (gpuMs > 0.0 ? gpuMs : wallMs));
    std::printf("agreement with the CPU runtime: worst relative difference %.3g (tolerance 2e-4), %zu non-finite\n", worst,
                nonFinite);
    return worst <= 2e-4 && nonFinite == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        return run(argc, argv);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
        return 2;
    }
}
