#include "device/vulkan_device.hpp"

#include "device/icd_diagnosis.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <dlfcn.h>
#include <link.h>
#include <utility>
#include <vector>

namespace voxtier {

namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitizerBuild = true;
#else
constexpr bool kSanitizerBuild = false;
#endif

/// Sanitizer builds only: marks every shared object loaded so far (the Vulkan driver, the
/// validation layer and what they pulled in) RTLD_NODELETE. The loader unloads drivers and layers
/// at vkDestroyInstance; allocations they keep until exit then have no module name, so the
/// LeakSanitizer/ThreadSanitizer suppressions for those libraries (tools/lsan.supp,
/// tools/tsan.supp) cannot match them and every Vulkan test fails on the driver's memory. Our own
/// Vulkan objects are still checked: the validation layer reports any we leak at teardown.
void pinLoadedLibrariesForSanitizers() {
    if (!kSanitizerBuild) return;
    dl_iterate_phdr(
        [](dl_phdr_info* info, std::size_t, void*) {
            if (info->dlpi_name && info->dlpi_name[0] == '/')
                if (void* h = dlopen(info->dlpi_name, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE))
                    dlclose(h);
            return 0;
        },
        nullptr);
}

} // namespace

// ---------------------------------------------------------------------------------------------
// Errors

const char* vkResultName(VkResult r) {
    switch (r) {
#define VT_CASE(x)                                                                                 \
    case x:                                                                                        \
        return #x;
        VT_CASE(VK_SUCCESS)
        VT_CASE(VK_NOT_READY)
        VT_CASE(VK_TIMEOUT)
        VT_CASE(VK_INCOMPLETE)
        VT_CASE(VK_ERROR_OUT_OF_HOST_MEMORY)
        VT_CASE(VK_ERROR_OUT_OF_DEVICE_MEMORY)
        VT_CASE(VK_ERROR_INITIALIZATION_FAILED)
        VT_CASE(VK_ERROR_DEVICE_LOST)
        VT_CASE(VK_ERROR_MEMORY_MAP_FAILED)
        VT_CASE(VK_ERROR_LAYER_NOT_PRESENT)
        VT_CASE(VK_ERROR_EXTENSION_NOT_PRESENT)
        VT_CASE(VK_ERROR_FEATURE_NOT_PRESENT)
        VT_CASE(VK_ERROR_INCOMPATIBLE_DRIVER)
        VT_CASE(VK_ERROR_TOO_MANY_OBJECTS)
        VT_CASE(VK_ERROR_FORMAT_NOT_SUPPORTED)
        VT_CASE(VK_ERROR_FRAGMENTED_POOL)
        VT_CASE(VK_ERROR_OUT_OF_POOL_MEMORY)
        VT_CASE(VK_ERROR_UNKNOWN)
#undef VT_CASE
    default:
        return "VkResult(?)";
    }
}

void throwVulkanFailure(VkResult r, const char* call, const char* file, int line) {
    // Keep the call short: the function name is what a reader needs, not its arguments.
    std::string name(call);
    if (const auto paren = name.find('('); paren != std::string::npos) name.resize(paren);
    const char* base = std::strrchr(file, '/');
    throw VulkanError(name + " failed: " + vkResultName(r) + " (" + (base ? base + 1 : file) + ":" +
                          std::to_string(line) + ")",
                      r);
}

// ---------------------------------------------------------------------------------------------
// Message log

bool validationRequestedByEnvironment() {
    const char* v = std::getenv("VOXTIER_VALIDATION");
    return v && std::strcmp(v, "1") == 0;
}

bool forcedStagingRequestedByEnvironment() {
    const char* v = std::getenv("VOXTIER_FORCE_STAGING");
    return v && std::strcmp(v, "1") == 0;
}

void VulkanMessageLog::add(std::string message) {
    std::lock_guard<std::mutex> lock(mutex_);
    messages_.push_back(std::move(message));
}

std::size_t VulkanMessageLog::count() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return messages_.size();
}

std::vector<std::string> VulkanMessageLog::messages() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return messages_;
}

std::string VulkanMessageLog::joined() const {
    std::string out;
    for (const auto& m : messages()) out += m + "\n";
    return out;
}

namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";

bool hasInstanceExtension(const char* name, const char* layer = nullptr) {
    std::uint32_t n = 0;
    if (vkEnumerateInstanceExtensionProperties(layer, &n, nullptr) != VK_SUCCESS) return false;
    std::vector<VkExtensionProperties> props(n);
    if (vkEnumerateInstanceExtensionProperties(layer, &n, props.data()) != VK_SUCCESS) return false;
    return std::any_of(props.begin(), props.end(),
                       [&](const auto& p) { return std::strcmp(p.extensionName, name) == 0; });
}

bool hasLayer(const char* name) {
    std::uint32_t n = 0;
    if (vkEnumerateInstanceLayerProperties(&n, nullptr) != VK_SUCCESS) return false;
    std::vector<VkLayerProperties> props(n);
    if (vkEnumerateInstanceLayerProperties(&n, props.data()) != VK_SUCCESS) return false;
    return std::any_of(props.begin(), props.end(),
                       [&](const auto& p) { return std::strcmp(p.layerName, name) == 0; });
}

/// Lower is better: a real GPU first, lavapipe (CPU) last.
int deviceRank(VkPhysicalDeviceType t) {
    switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
        return 0;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
        return 1;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
        return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
        return 3;
    default:
        return 4;
    }
}

bool supportsFormat(VkPhysicalDevice pd, VkFormat f, VkFormatFeatureFlags need) {
    VkFormatProperties p{};
    vkGetPhysicalDeviceFormatProperties(pd, f, &p);
    return (p.optimalTilingFeatures & need) == need;
}

/// The graphics queue family of a device that can run the near tier, or -1.
int usableQueueFamily(VkPhysicalDevice pd) {
    VkPhysicalDeviceProperties props{};
    vkGetPhysicalDeviceProperties(pd, &props);
    if (props.apiVersion < VK_API_VERSION_1_2) return -1;
    // The formats the near tier renders into and samples from (exact integers, float depth).
    if (!supportsFormat(pd, VK_FORMAT_R32_UINT,
                        VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT |
                            VK_FORMAT_FEATURE_TRANSFER_SRC_BIT) ||
        !supportsFormat(pd, VK_FORMAT_D32_SFLOAT,
                        VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT |
                            VK_FORMAT_FEATURE_TRANSFER_SRC_BIT) ||
        !supportsFormat(pd, VK_FORMAT_R8_UINT,
                        VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT | VK_FORMAT_FEATURE_TRANSFER_DST_BIT))
        return -1;
    std::uint32_t n = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, nullptr);
    std::vector<VkQueueFamilyProperties> families(n);
    vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, families.data());
    for (std::uint32_t i = 0; i < n; ++i)
        if (families[i].queueFlags & VK_QUEUE_GRAPHICS_BIT) return int(i);
    return -1;
}

/// The device VulkanDevice and probeVulkanDevice both pick: the best-ranked usable one (a GPU if
/// present, lavapipe otherwise), with its queue family; null when none is usable.
struct ChosenDevice {
    VkPhysicalDevice device = VK_NULL_HANDLE;
    std::uint32_t queueFamily = 0;
};
ChosenDevice chooseDevice(const std::vector<VkPhysicalDevice>& devices) {
    ChosenDevice chosen;
    int bestRank = 1 << 30;
    for (VkPhysicalDevice pd : devices) {
        const int family = usableQueueFamily(pd);
        if (family < 0) continue;
        VkPhysicalDeviceProperties props{};
        vkGetPhysicalDeviceProperties(pd, &props);
        if (deviceRank(props.deviceType) < bestRank) {
            bestRank = deviceRank(props.deviceType);
            chosen = {pd, std::uint32_t(family)};
        }
    }
    return chosen;
}

} // namespace

// ---------------------------------------------------------------------------------------------
// Device

VKAPI_ATTR VkBool32 VKAPI_CALL VulkanDevice::onMessage(
    VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT type,
    const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
    const auto* sink = static_cast<const MessageSink*>(user);
    std::string text = (type & VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT)    ? "validation"
                       : (type & VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT) ? "performance"
                                                                                  : "general";
    text += (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) ? " error: " : " warning: ";
    text += data && data->pMessage ? data->pMessage : "(no text)";
    // Loader chatter ("general") is recorded but not echoed: when there is no driver at all the
    // loader explains itself in several lines, and the CLI promises one line (ours).
    if (sink->echo && !(type & VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT))
        std::fprintf(stderr, "voxtier: vulkan %s\n", text.c_str());
    sink->log->add(std::move(text));
    return VK_FALSE;
}

VulkanProbe probeVulkanDevice() {
    VulkanProbe probe;
    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.pApplicationName = "voxtier";
    app.pEngineName = "voxtier";
    app.apiVersion = VK_API_VERSION_1_2;
    VkInstanceCreateInfo ici{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    ici.pApplicationInfo = &app;
    VkInstance instance = VK_NULL_HANDLE;
    const VkResult created = vkCreateInstance(&ici, nullptr, &instance);
    if (created != VK_SUCCESS) {
        probe.whyNone = created == VK_ERROR_INCOMPATIBLE_DRIVER
                            ? noVulkanDeviceMessage()
                            : std::string("vkCreateInstance: ") + vkResultName(created);
        return probe;
    }
    const std::vector<VkPhysicalDevice> devices = physicalDevicesOf(instance);
    pinLoadedLibrariesForSanitizers(); // drivers and layers are loaded by now
    if (const VkPhysicalDevice pd = chooseDevice(devices).device) {
        VkPhysicalDeviceProperties props{};
        vkGetPhysicalDeviceProperties(pd, &props);
        probe.found = true;
        probe.cpu = props.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
        probe.name = props.deviceName;
        VkPhysicalDeviceFeatures features{};
        vkGetPhysicalDeviceFeatures(pd, &features);
        probe.float64 = features.shaderFloat64 == VK_TRUE;
    }
    if (!probe.found) probe.whyNone = noVulkanDeviceMessage();
    vkDestroyInstance(instance, nullptr);
    return probe;
}

VulkanDevice::VulkanDevice(const VulkanDeviceOptions& options,
                           std::shared_ptr<VulkanMessageLog> log)
    : log_(log ? std::move(log) : std::make_shared<VulkanMessageLog>()),
      validation_(options.validation || validationRequestedByEnvironment()),
      echo_(options.echoMessages) {
    placementOptions_.forceStaging = options.forceStaging || forcedStagingRequestedByEnvironment();
    try {
        sink_ = std::make_unique<MessageSink>(MessageSink{log_.get(), echo_});
        createInstance(options);
        pickPhysicalDevice();
        createLogicalDevice();
    } catch (...) {
        destroy();
        throw;
    }
}

void VulkanDevice::createInstance(const VulkanDeviceOptions& options) {
    const bool debugUtils = hasInstanceExtension(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    if (validation_ && !hasLayer(kValidationLayer))
        throw VulkanError(std::string("validation requested but ") + kValidationLayer +
                          " is not installed (Debian: vulkan-validationlayers)");
    if (validation_ && !debugUtils)
        throw VulkanError("validation requested but the loader lacks VK_EXT_debug_utils");

    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.pApplicationName = "voxtier";
    app.pEngineName = "voxtier";
    app.apiVersion = VK_API_VERSION_1_2;

    std::vector<const char*> extensions;
    std::vector<const char*> layers;
    if (debugUtils) extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    if (validation_) layers.push_back(kValidationLayer);

    // Warnings and errors only: the loader's and the layer's info output is not a finding.
    VkDebugUtilsMessengerCreateInfoEXT messengerInfo{
        VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
    messengerInfo.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                                    VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    messengerInfo.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                                VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                                VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
    messengerInfo.pfnUserCallback = onMessage;
    messengerInfo.pUserData = sink_.get();

    VkInstanceCreateInfo ici{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    ici.pApplicationInfo = &app;
    ici.enabledExtensionCount = std::uint32_t(extensions.size());
    ici.ppEnabledExtensionNames = extensions.data();
    ici.enabledLayerCount = std::uint32_t(layers.size());
    ici.ppEnabledLayerNames = layers.data();
    // Chained messenger: also catches what the loader says during vkCreateInstance and what
    // the layer reports during vkDestroyInstance (leaked objects), and keeps the loader from
    // printing to stderr itself.
    const void* chain = nullptr;
    if (debugUtils) {
        messengerInfo.pNext = chain;
        chain = &messengerInfo;
    }
    const VkValidationFeatureEnableEXT syncValidation =
        VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT;
    VkValidationFeaturesEXT features{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
    if (validation_ && options.synchronizationValidation &&
        hasInstanceExtension(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME, kValidationLayer)) {
        features.enabledValidationFeatureCount = 1;
        features.pEnabledValidationFeatures = &syncValidation;
        features.pNext = chain;
        chain = &features;
        extensions.push_back(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME);
        ici.enabledExtensionCount = std::uint32_t(extensions.size());
        ici.ppEnabledExtensionNames = extensions.data();
    }
    ici.pNext = chain;

    const VkResult created = vkCreateInstance(&ici, nullptr, &instance_);
    if (created == VK_ERROR_INCOMPATIBLE_DRIVER)
        throw VulkanError(noVulkanDeviceMessage(), created);
    VK_CHECK(created);

    if (debugUtils) {
        auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
        if (create) {
            messengerInfo.pNext = nullptr;
            VK_CHECK(create(instance_, &messengerInfo, nullptr, &messenger_));
        }
    }
}

void VulkanDevice::pickPhysicalDevice() {
    const std::vector<VkPhysicalDevice> devices = physicalDevicesOf(instance_);
    pinLoadedLibrariesForSanitizers(); // drivers and layers are loaded by now
    const ChosenDevice chosen = chooseDevice(devices);
    if (!chosen.device) throw VulkanError(noVulkanDeviceMessage(), VK_ERROR_INCOMPATIBLE_DRIVER);
    physical_ = chosen.device;
    queueFamily_ = chosen.queueFamily;
    vkGetPhysicalDeviceProperties(physical_, &properties_);
    std::uint32_t n = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(physical_, &n, nullptr);
    std::vector<VkQueueFamilyProperties> families(n);
    vkGetPhysicalDeviceQueueFamilyProperties(physical_, &n, families.data());
    timestampValidBits_ = families[queueFamily_].timestampValidBits;
    vkGetPhysicalDeviceMemoryProperties(physical_, &memory_);
    name_ = properties_.deviceName;
}

void VulkanDevice::createLogicalDevice() {
    VkPhysicalDeviceFeatures available{};
    vkGetPhysicalDeviceFeatures(physical_, &available);
    VkPhysicalDeviceFeatures enabled{};
    pipelineStatistics_ = available.pipelineStatisticsQuery == VK_TRUE;
    fragmentAtomics_ = available.fragmentStoresAndAtomics == VK_TRUE;
    enabled.pipelineStatisticsQuery = available.pipelineStatisticsQuery;
    enabled.fragmentStoresAndAtomics = available.fragmentStoresAndAtomics;
    // The far pass maps near cells to snapshot cells in double, as the CPU blit does.
    float64_ = available.shaderFloat64 == VK_TRUE;
    enabled.shaderFloat64 = available.shaderFloat64;
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo qci{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    qci.queueFamilyIndex = queueFamily_;
    qci.queueCount = 1;
    qci.pQueuePriorities = &priority;
    VkDeviceCreateInfo dci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    dci.queueCreateInfoCount = 1;
    dci.pQueueCreateInfos = &qci;
    dci.pEnabledFeatures = &enabled;
    VK_CHECK(vkCreateDevice(physical_, &dci, nullptr, &device_));
    vkGetDeviceQueue(device_, queueFamily_, 0, &queue_);

    VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pci.queueFamilyIndex = queueFamily_;
    VK_CHECK(vkCreateCommandPool(device_, &pci, nullptr, &pool_));
    VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VK_CHECK(vkCreateFence(device_, &fci, nullptr, &fence_));
}

VulkanDevice::~VulkanDevice() {
    destroy();
}

void VulkanDevice::destroy() noexcept {
    if (device_) {
        vkDeviceWaitIdle(device_);
        if (fence_) vkDestroyFence(device_, fence_, nullptr);
        if (pool_) vkDestroyCommandPool(device_, pool_, nullptr);
        vkDestroyDevice(device_, nullptr);
    }
    fence_ = VK_NULL_HANDLE;
    pool_ = VK_NULL_HANDLE;
    device_ = VK_NULL_HANDLE;
    if (instance_) {
        if (messenger_) {
            auto destroyMessenger = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
                vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
            if (destroyMessenger) destroyMessenger(instance_, messenger_, nullptr);
        }
        vkDestroyInstance(instance_, nullptr);
    }
    messenger_ = VK_NULL_HANDLE;
    instance_ = VK_NULL_HANDLE;
}

std::uint32_t VulkanDevice::memoryType(std::uint32_t typeBits,
                                       VkMemoryPropertyFlags required) const {
    for (std::uint32_t i = 0; i < memory_.memoryTypeCount; ++i)
        if ((typeBits & (1u << i)) && (memory_.memoryTypes[i].propertyFlags & required) == required)
            return i;
    throw VulkanError("no Vulkan memory type with the required properties",
                      VK_ERROR_OUT_OF_DEVICE_MEMORY);
}

MemoryPlacement VulkanDevice::placementFor(BufferClass c, std::uint32_t typeBits) const {
    const std::optional<MemoryPlacement> p = placeBuffer(memory_, typeBits, c, placementOptions_);
    if (!p)
        throw VulkanError(std::string("no Vulkan memory type for a ") + bufferClassName(c) +
                              " buffer on " + name_,
                          VK_ERROR_OUT_OF_DEVICE_MEMORY);
    return *p;
}

VkCommandBuffer VulkanDevice::allocateCommandBuffer() {
    VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    ai.commandPool = pool_;
    ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ai.commandBufferCount = 1;
    VkCommandBuffer cb = VK_NULL_HANDLE;
    VK_CHECK(vkAllocateCommandBuffers(device_, &ai, &cb));
    return cb;
}

void VulkanDevice::freeCommandBuffer(VkCommandBuffer cb) {
    if (cb) vkFreeCommandBuffers(device_, pool_, 1, &cb);
}

void VulkanDevice::submitAndWait(VkCommandBuffer cb) {
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cb;
    VK_CHECK(vkResetFences(device_, 1, &fence_));
    VK_CHECK(vkQueueSubmit(queue_, 1, &si, fence_));
    VK_CHECK(vkWaitForFences(device_, 1, &fence_, VK_TRUE, UINT64_MAX));
}

// ---------------------------------------------------------------------------------------------
// Resources

VulkanBuffer::VulkanBuffer(VulkanDevice& device, VkDeviceSize size, VkBufferUsageFlags usage,
                           BufferClass bufferClass) {
    switch (bufferClass) {
    case BufferClass::ShaderRead:
        // Whether it will be staged is known only from the requirements; TRANSFER_DST costs
        // nothing on the direct path and keeps the requirements the same either way.
    case BufferClass::Readback:
        usage |= VK_BUFFER_USAGE_TRANSFER_DST_BIT;
        break;
    case BufferClass::Staging:
        usage |= VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
        break;
    case BufferClass::DeviceOnly:
        break;
    }
    create(device, size, usage, bufferClass, false);
}

VulkanBuffer::VulkanBuffer(VulkanDevice& device, VkDeviceSize size, VkBufferUsageFlags usage,
                           bool hostVisible) {
    create(device, size, usage, std::nullopt, hostVisible);
}

void VulkanBuffer::create(VulkanDevice& device, VkDeviceSize size, VkBufferUsageFlags usage,
                          std::optional<BufferClass> bufferClass, bool hostVisible) {
    device_ = device.device();
    size_ = size;
    atom_ = std::max<VkDeviceSize>(1, device.nonCoherentAtomSize());
    try {
        VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
        bci.size = size;
        bci.usage = usage;
        bci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
        VK_CHECK(vkCreateBuffer(device_, &bci, nullptr, &buffer_));
        VkMemoryRequirements req{};
        vkGetBufferMemoryRequirements(device_, buffer_, &req);
        if (bufferClass) {
            placement_ = device.placementFor(*bufferClass, req.memoryTypeBits);
        } else {
            // The pre-policy choice, unchanged: coherent host-visible, or device-local.
            const VkPhysicalDeviceMemoryProperties& m = device.memoryProperties();
            placement_.typeIndex = device.memoryType(
                req.memoryTypeBits, hostVisible ? VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
                                                      VK_MEMORY_PROPERTY_HOST_COHERENT_BIT
                                                : VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
            placement_.flags = m.memoryTypes[placement_.typeIndex].propertyFlags;
            placement_.heapIndex = m.memoryTypes[placement_.typeIndex].heapIndex;
            placement_.heapSize = m.memoryHeaps[placement_.heapIndex].size;
            placement_.hostWrite = hostVisible ? HostWrite::Direct : HostWrite::None;
            placement_.mapped = hostVisible;
        }
        VkMemoryAllocateInfo mai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
        mai.allocationSize = req.size;
        mai.memoryTypeIndex = placement_.typeIndex;
        VK_CHECK(vkAllocateMemory(device_, &mai, nullptr, &memory_));
        allocationSize_ = req.size;
        VK_CHECK(vkBindBufferMemory(device_, buffer_, memory_, 0));
        if (placement_.mapped)
            VK_CHECK(vkMapMemory(device_, memory_, 0, VK_WHOLE_SIZE, 0, &mapped_));
    } catch (...) {
        reset();
        throw;
    }
}

VkMappedMemoryRange VulkanBuffer::atomRange(VkDeviceSize offset, VkDeviceSize bytes) const {
    VkMappedMemoryRange r{VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE};
    r.memory = memory_;
    r.offset = offset / atom_ * atom_;
    if (bytes == VK_WHOLE_SIZE || offset + bytes >= allocationSize_) {
        r.size = VK_WHOLE_SIZE;
    } else {
        const VkDeviceSize end = (offset + bytes + atom_ - 1) / atom_ * atom_;
        r.size = std::min(end, allocationSize_) - r.offset;
    }
    return r;
}

void VulkanBuffer::write(VkDeviceSize offset, const void* data, VkDeviceSize bytes) {
    if (placement_.hostWrite != HostWrite::Direct || !mapped_)
        throw VulkanError("VulkanBuffer::write on a buffer the host cannot write directly (" +
                          std::string(hostWriteName(placement_.hostWrite)) + ")");
    if (offset > size_ || bytes > size_ - offset)
        throw VulkanError("VulkanBuffer::write of " + std::to_string(bytes) + " bytes at " +
                          std::to_string(offset) + " past the end of a " + std::to_string(size_) +
                          "-byte buffer");
    if (bytes == 0) return;
    std::memcpy(static_cast<char*>(mapped_) + offset, data, std::size_t(bytes));
    flush(offset, bytes);
}

void VulkanBuffer::flush(VkDeviceSize offset, VkDeviceSize bytes) {
    if (!mapped_ || (placement_.flags & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT)) return;
    const VkMappedMemoryRange r = atomRange(offset, bytes);
    VK_CHECK(vkFlushMappedMemoryRanges(device_, 1, &r));
}

void VulkanBuffer::invalidateForRead(VkDeviceSize offset, VkDeviceSize bytes) {
    if (!mapped_ || (placement_.flags & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT)) return;
    const VkMappedMemoryRange r = atomRange(offset, bytes);
    VK_CHECK(vkInvalidateMappedMemoryRanges(device_, 1, &r));
}

VulkanBuffer& VulkanBuffer::operator=(VulkanBuffer&& o) noexcept {
    if (this != &o) {
        reset();
        std::swap(device_, o.device_);
        std::swap(buffer_, o.buffer_);
        std::swap(memory_, o.memory_);
        std::swap(size_, o.size_);
        std::swap(allocationSize_, o.allocationSize_);
        std::swap(atom_, o.atom_);
        std::swap(mapped_, o.mapped_);
        std::swap(placement_, o.placement_);
    }
    return *this;
}

void VulkanBuffer::reset() noexcept {
    if (buffer_) vkDestroyBuffer(device_, buffer_, nullptr);
    if (memory_) vkFreeMemory(device_, memory_, nullptr); // unmaps implicitly
    buffer_ = VK_NULL_HANDLE;
    memory_ = VK_NULL_HANDLE;
    mapped_ = nullptr;
    size_ = 0;
    allocationSize_ = 0;
    placement_ = MemoryPlacement{};
}

VulkanImage::VulkanImage(VulkanDevice& device, VkImageType type, VkFormat format, VkExtent3D extent,
                         VkImageUsageFlags usage, VkImageAspectFlags aspect)
    : device_(device.device()), extent_(extent), format_(format), aspect_(aspect) {
    try {
        VkImageCreateInfo ici{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
        ici.imageType = type;
        ici.format = format;
        ici.extent = extent;
        ici.mipLevels = 1;
        ici.arrayLayers = 1;
        ici.samples = VK_SAMPLE_COUNT_1_BIT;
        ici.tiling = VK_IMAGE_TILING_OPTIMAL;
        ici.usage = usage;
        ici.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
        ici.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
        VK_CHECK(vkCreateImage(device_, &ici, nullptr, &image_));
        VkMemoryRequirements req{};
        vkGetImageMemoryRequirements(device_, image_, &req);
        VkMemoryAllocateInfo mai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
        mai.allocationSize = req.size;
        mai.memoryTypeIndex =
            device.memoryType(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
        VK_CHECK(vkAllocateMemory(device_, &mai, nullptr, &memory_));
        VK_CHECK(vkBindImageMemory(device_, image_, memory_, 0));
        VkImageViewCreateInfo vci{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
        vci.image = image_;
        vci.viewType = type == VK_IMAGE_TYPE_3D ? VK_IMAGE_VIEW_TYPE_3D : VK_IMAGE_VIEW_TYPE_2D;
        vci.format = format;
        vci.subresourceRange = {aspect, 0, 1, 0, 1};
        VK_CHECK(vkCreateImageView(device_, &vci, nullptr, &view_));
    } catch (...) {
        reset();
        throw;
    }
}

VulkanImage& VulkanImage::operator=(VulkanImage&& o) noexcept {
    if (this != &o) {
        reset();
        std::swap(device_, o.device_);
        std::swap(image_, o.image_);
        std::swap(view_, o.view_);
        std::swap(memory_, o.memory_);
        std::swap(extent_, o.extent_);
        std::swap(format_, o.format_);
        std::swap(aspect_, o.aspect_);
    }
    return *this;
}

void VulkanImage::reset() noexcept {
    if (view_) vkDestroyImageView(device_, view_, nullptr);
    if (image_) vkDestroyImage(device_, image_, nullptr);
    if (memory_) vkFreeMemory(device_, memory_, nullptr);
    view_ = VK_NULL_HANDLE;
    image_ = VK_NULL_HANDLE;
    memory_ = VK_NULL_HANDLE;
    extent_ = {0, 0, 0};
}

std::vector<VkPhysicalDevice> physicalDevicesOf(VkInstance instance) {
    std::uint32_t count = 0;
    std::vector<VkPhysicalDevice> devices;
    if (vkEnumeratePhysicalDevices(instance, &count, nullptr) == VK_SUCCESS && count) {
        devices.resize(count);
        if (vkEnumeratePhysicalDevices(instance, &count, devices.data()) != VK_SUCCESS)
            devices.clear();
    }
    return devices;
}

void imageBarrier(VkCommandBuffer cb, VkImage image, VkImageAspectFlags aspect, VkImageLayout from,
                  VkImageLayout to, VkPipelineStageFlags srcStage, VkAccessFlags srcAccess,
                  VkPipelineStageFlags dstStage, VkAccessFlags dstAccess) {
    VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
    b.srcAccessMask = srcAccess;
    b.dstAccessMask = dstAccess;
    b.oldLayout = from;
    b.newLayout = to;
    b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.image = image;
    b.subresourceRange = {aspect, 0, 1, 0, 1};
    vkCmdPipelineBarrier(cb, srcStage, dstStage, 0, 0, nullptr, 0, nullptr, 1, &b);
}

void bufferBarrier(VkCommandBuffer cb, VkBuffer buffer, VkPipelineStageFlags srcStage,
                   VkAccessFlags srcAccess, VkPipelineStageFlags dstStage,
                   VkAccessFlags dstAccess) {
    VkBufferMemoryBarrier b{VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER};
    b.srcAccessMask = srcAccess;
    b.dstAccessMask = dstAccess;
    b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.buffer = buffer;
    b.size = VK_WHOLE_SIZE;
    vkCmdPipelineBarrier(cb, srcStage, dstStage, 0, 0, nullptr, 1, &b, 0, nullptr);
}

VkShaderModule createShaderModule(VkDevice device, std::span<const std::uint32_t> code) {
    VkShaderModuleCreateInfo mi{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    mi.codeSize = code.size_bytes();
    mi.pCode = code.data();
    VkShaderModule module = VK_NULL_HANDLE;
    VK_CHECK(vkCreateShaderModule(device, &mi, nullptr, &module));
    return module;
}

void createPassLayouts(VkDevice device, std::span<const VkDescriptorSetLayoutBinding> bindings,
                       std::uint32_t pushBytes, VkDescriptorSetLayout& setLayout,
                       VkPipelineLayout& pipelineLayout) {
    VkDescriptorSetLayoutCreateInfo dli{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    dli.bindingCount = std::uint32_t(bindings.size());
    dli.pBindings = bindings.data();
    VK_CHECK(vkCreateDescriptorSetLayout(device, &dli, nullptr, &setLayout));
    VkPipelineLayoutCreateInfo pli{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pli.setLayoutCount = 1;
    pli.pSetLayouts = &setLayout;
    const VkPushConstantRange push{VK_SHADER_STAGE_COMPUTE_BIT, 0, pushBytes};
    pli.pushConstantRangeCount = 1;
    pli.pPushConstantRanges = &push;
    VK_CHECK(vkCreatePipelineLayout(device, &pli, nullptr, &pipelineLayout));
}

VkPipeline createComputePipeline(VkDevice device, VkPipelineLayout layout,
                                 std::span<const std::uint32_t> code,
                                 std::span<const std::uint32_t> specialization) {
    VkShaderModule module = createShaderModule(device, code);
    // Constant k (constant_id = k in the shader) is specialization[k], a 32-bit value.
    std::vector<VkSpecializationMapEntry> entries;
    for (std::uint32_t k = 0; k < specialization.size(); ++k)
        entries.push_back({k, k * std::uint32_t(sizeof(std::uint32_t)), sizeof(std::uint32_t)});
    const VkSpecializationInfo info{std::uint32_t(entries.size()), entries.data(),
                                    specialization.size_bytes(), specialization.data()};
    VkComputePipelineCreateInfo cpi{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    cpi.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                 nullptr,
                 0,
                 VK_SHADER_STAGE_COMPUTE_BIT,
                 module,
                 "main",
                 specialization.empty() ? nullptr : &info};
    cpi.layout = layout;
    VkPipeline pipeline = VK_NULL_HANDLE;
    const VkResult r =
        vkCreateComputePipelines(device, VK_NULL_HANDLE, 1, &cpi, nullptr, &pipeline);
    vkDestroyShaderModule(device, module, nullptr);
    VK_CHECK(r);
    return pipeline;
}

} // namespace voxtier
