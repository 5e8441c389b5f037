#include "device/pass_timer.hpp"

#include "device/vulkan_device.hpp"

namespace voxtier {

double timestampDeltaMs(std::uint64_t begin, std::uint64_t end, std::uint32_t validBits,
                        double periodNs) {
    const std::uint64_t mask =
        validBits >= 64 ? ~std::uint64_t(0) : (std::uint64_t(1) << validBits) - 1;
    // Unsigned subtraction in the counter's width also covers one wrap between the two.
    const std::uint64_t ticks = ((end & mask) - (begin & mask)) & mask;
    return double(ticks) * periodNs * 1e-6;
}

PassTimer::PassTimer(VulkanDevice& device, std::uint32_t maxPasses, bool forceUnavailable)
    : device_(device.device()), maxPasses_(maxPasses), validBits_(device.timestampValidBits()),
      periodNs_(device.timestampPeriod()) {
    if (forceUnavailable || validBits_ == 0 || maxPasses_ == 0) return;
    VkQueryPoolCreateInfo qci{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    qci.queryType = VK_QUERY_TYPE_TIMESTAMP;
    qci.queryCount = 2 * maxPasses_;
    VK_CHECK(vkCreateQueryPool(device_, &qci, nullptr, &pool_));
}

PassTimer::~PassTimer() {
    if (pool_) vkDestroyQueryPool(device_, pool_, nullptr);
}

void PassTimer::reset(VkCommandBuffer cb) {
    passes_.clear();
    open_.clear();
    if (pool_) vkCmdResetQueryPool(cb, pool_, 0, 2 * maxPasses_);
}

void PassTimer::begin(VkCommandBuffer cb, std::string_view name) {
    if (!pool_ || passes_.size() >= maxPasses_) {
        open_.push_back(std::nullopt);
        return;
    }
    const auto query = std::uint32_t(2 * passes_.size());
    passes_.push_back(Pass{std::string(name), query, false});
    open_.push_back(passes_.size() - 1);
    vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, pool_, query);
}

void PassTimer::end(VkCommandBuffer cb) {
    if (open_.empty()) return; // an end() without begin() times nothing
    const std::optional<std::size_t> index = open_.back();
    open_.pop_back();
    if (!index) return;
    Pass& p = passes_[*index];
    // BOTTOM_OF_PIPE: the timestamp is written once all earlier commands have completed.
    vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, pool_, p.query + 1);
    p.closed = true;
}

std::vector<PassTime> PassTimer::results() const {
    std::vector<PassTime> out;
    if (!pool_) return out;
    for (const Pass& p : passes_) {
        // A pass never closed has an unwritten end query, whose result would never be ready.
        if (!p.closed) continue;
        std::uint64_t ticks[2] = {0, 0};
        const VkResult r = vkGetQueryPoolResults(device_, pool_, p.query, 2, sizeof ticks, ticks,
                                                 sizeof(std::uint64_t), VK_QUERY_RESULT_64_BIT);
        if (r == VK_NOT_READY)
            throw VulkanError("PassTimer::results before the frame's fence signalled", r);
        VK_CHECK(r);
        out.push_back(
            PassTime{p.name, timestampDeltaMs(ticks[0], ticks[1], validBits_, periodNs_)});
    }
    return out;
}

std::optional<double> PassTimer::ms(std::string_view name) const {
    for (const PassTime& t : results())
        if (t.name == name) return t.ms;
    return std::nullopt;
}

} // namespace voxtier
