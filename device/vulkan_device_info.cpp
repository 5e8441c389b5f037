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
