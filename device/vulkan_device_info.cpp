#include "device/vulkan_device_info.hpp"

#include "device/vulkan_device.hpp"
#include "device/vulkan_options.hpp"

#include <vulkan/vulkan.h>

#include <vector>

namespace voxtier {

namespace {

const char* typeName(VkPhysicalDeviceType t) {
    switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
        return "discrete GPU";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
        return "integrated GPU";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
        return "virtual GPU";
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
        return "CPU";
    default:
        return "other";
    }
}

std::string versionText(std::uint32_t v) {
    return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v)) +
           "." + std::to_string(VK_API_VERSION_PATCH(v));
}

} // namespace

std::vector<std::string> describeMemoryPlacements() {
    std::vector<std::string> lines;
    try {
        VulkanDeviceOptions options;
        options.echoMessages = false;
        VulkanDevice device(options);
        for (BufferClass c : kAllBufferClasses) {
            // The usage a buffer of the class typically has; the constructor adds the transfer
            // bits (VulkanBuffer), which can narrow memoryTypeBits on some drivers.
            VkBufferUsageFlags usage = 0;
            switch (c) {
            case BufferClass::ShaderRead:
                usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT |
                        VK_BUFFER_USAGE_TRANSFER_DST_BIT;
                break;
            case BufferClass::DeviceOnly:
                usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
                break;
            case BufferClass::Staging:
                usage = VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
                break;
            case BufferClass::Readback:
                usage = VK_BUFFER_USAGE_TRANSFER_DST_BIT;
                break;
            }
            VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
            bci.size = 4096;
            bci.usage = usage;
            bci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
            VkBuffer buffer = VK_NULL_HANDLE;
            VK_CHECK(vkCreateBuffer(device.device(), &bci, nullptr, &buffer));
            VkMemoryRequirements req{};
            vkGetBufferMemoryRequirements(device.device(), buffer, &req);
            vkDestroyBuffer(device.device(), buffer, nullptr);
            lines.push_back(std::string(bufferClassName(c)) + ": " +
                            describePlacement(device.placementFor(c, req.memoryTypeBits)));
        }
    } catch (const std::exception&) {
        lines.clear();
    }
    return lines;
}

std::string VulkanDeviceInfo::summary() const {
    if (!found) return whyNone;
    return name + " (" + type + "; driver " + driver + "; Vulkan " + apiVersion + ")";
}

VulkanDeviceInfo describeVulkanDevice() {
    VulkanDeviceInfo info;
    // The device the near tier picks (probeVulkanDevice's ranking), then its properties by name.
    const VulkanProbe probe = probeVulkanDevice();
    if (!probe.found) {
        info.whyNone = probe.whyNone;
        return info;
    }
    info.found = true;
    info.name = probe.name;
    info.type = probe.cpu ? "CPU" : "GPU";
    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.pApplicationName = "voxtier";
    app.apiVersion = VK_API_VERSION_1_2;
    VkInstanceCreateInfo ici{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    ici.pApplicationInfo = &app;
    VkInstance instance = VK_NULL_HANDLE;
    if (vkCreateInstance(&ici, nullptr, &instance) != VK_SUCCESS) return info;
    const std::vector<VkPhysicalDevice> devices = physicalDevicesOf(instance);
    for (VkPhysicalDevice pd : devices) {
        VkPhysicalDeviceDriverProperties driver{
            VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
        VkPhysicalDeviceProperties2 props{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
        props.pNext = &driver;
        vkGetPhysicalDeviceProperties2(pd, &props);
        if (probe.name != props.properties.deviceName) continue;
        info.type = typeName(props.properties.deviceType);
        info.driver = std::string(driver.driverName) +
                      (driver.driverInfo[0] ? " " + std::string(driver.driverInfo) : "");
        info.apiVersion = versionText(props.properties.apiVersion);
        break;
    }
    vkDestroyInstance(instance, nullptr);
    return info;
}

} // namespace voxtier
