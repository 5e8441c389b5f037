// The versioned LRU under the snapshot cache (impostor_cache/versioned_lru.hpp): eviction order,
// byte and entry budgets, one production per entry however many threads ask, the newest older
// version handed to the producer and dropped when the new value lands, failed productions
// retried. Values are tagged blobs, so every expectation is counted by hand.
#include "impostor_cache/versioned_lru.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace voxtier {
namespace {

struct Blob {
    std::size_t size = 1;
    std::string tag;
    std::size_t bytes() const { return size; }
};

using Lru = VersionedLru<std::string, Blob>;
using Older = Lru::Older;

/// A producer that makes Blob{size, tag}, records the Older it was handed and counts its calls.
struct Maker {
    std::size_t size = 1;
    std::string tag;
    int* calls = nullptr;
    std::optional<Older>* seen = nullptr;
    Lru::Value operator()(const std::optional<Older>& older) const {
        if (calls) ++*calls;
        if (seen) *seen = older;
        return std::make_shared<const Blob>(Blob{size, tag});
    }
};

Lru::Value request(Lru& lru, const std::string& key, std::uint64_t version = 1) {
    return lru.get(key, version, Maker{1, key + "@" + std::to_string(version)});
}

TEST(VersionedLru, EvictsTheLeastRecentlyUsedOverAnEntryBudget) {
    Lru lru(LruBudget{.entries = 3});
    for (const char* k : {"a", "b", "c"}) request(lru, k);
    request(lru, "a"); // touched: now b is the least recently used
    request(lru, "d");
    EXPECT_EQ(lru.find("b", 1), nullptr);
    for (const char* k : {"a", "c", "d"}) EXPECT_NE(lru.find(k, 1), nullptr) << k;
    request(lru, "e"); // c is next
    EXPECT_EQ(lru.find("c", 1), nullptr);
    const LruStats s = lru.stats();
    EXPECT_EQ(s.evictions, 2u);
    EXPECT_EQ(s.entries, 3u);
    EXPECT_EQ(s.misses, 5u);
    EXPECT_EQ(s.hits, 1u);
}

TEST(VersionedLru, FindNeitherCountsNorReorders) {
    Lru lru(LruBudget{.entries = 2});
    request(lru, "a");
    request(lru, "b");
    EXPECT_NE(lru.find("a", 1), nullptr); // not a use: a stays the least recently used
    EXPECT_EQ(lru.find("a", 2), nullptr);
    EXPECT_EQ(lru.find("z", 1), nullptr);
    request(lru, "c");
    EXPECT_EQ(lru.find("a", 1), nullptr);
    EXPECT_EQ(lru.stats().hits, 0u);
    EXPECT_EQ(lru.stats().misses, 3u);
}

// contains() is find() != nullptr without taking a share of the value: listed entries only (not
// evicted, superseded or still in production); readers on threads of their own share the lock
// while a writer lists and evicts entries (ThreadSanitizer checks them in the tsan preset).
TEST(VersionedLru, ContainsIsFindWithoutTheValue) {
    Lru lru(LruBudget{.entries = 2});
    request(lru, "a", 1);
    request(lru, "b", 1);
    request(lru, "a", 3); // supersedes a@1
    request(lru, "c", 1); // evicts b@1
    for (const auto& [key, version] : std::vector<std::pair<std::string, std::uint64_t>>{
             {"a", 1}, {"a", 3}, {"b", 1}, {"c", 1}, {"c", 2}, {"z", 1}})
        EXPECT_EQ(lru.contains(key, version), lru.find(key, version) != nullptr)
            << key << "@" << version;
    EXPECT_TRUE(lru.contains("a", 3));
    EXPECT_FALSE(lru.contains("b", 1));

    // In production: not listed yet.
    std::atomic<bool> producing{false}, release{false};
    std::thread producer([&] {
        lru.get("p", 1, [&](const std::optional<Older>&) {
            producing = true;
            while (!release.load()) std::this_thread::yield();
            return std::make_shared<const Blob>(Blob{1, "p"});
        });
    });
    while (!producing.load()) std::this_thread::yield();
    EXPECT_FALSE(lru.contains("p", 1));
    release = true;
    producer.join();
    EXPECT_TRUE(lru.contains("p", 1));

    // Readers beside a writer.
    std::atomic<bool> done{false};
    std::atomic<int> seen{0};
    std::vector<std::thread> readers;
    for (int t = 0; t < 4; ++t)
        readers.emplace_back([&] {
            while (!done.load()) seen += lru.contains("p", 1) ? 1 : 0;
        });
    for (int k = 0; k < 200; ++k) request(lru, "w" + std::to_string(k));
    done = true;
    for (auto& t : readers) t.join();
    EXPECT_FALSE(lru.contains("p", 1)); // evicted by the writer's entries
    EXPECT_EQ(lru.stats().entries, 2u);
}

TEST(VersionedLru, KeepsTheByteBudgetAndHandedOutValuesOutliveEviction) {
    Lru lru(LruBudget{.bytes = 100});
    const Lru::Value first = lru.get("a", 1, Maker{40, "a"});
    lru.get("b", 1, Maker{40, "b"});
    EXPECT_EQ(lru.stats().bytes, 80u);
    lru.get("c", 1, Maker{40, "c"}); // 120 > 100: a goes
    EXPECT_EQ(lru.stats().bytes, 80u);
    EXPECT_EQ(lru.find("a", 1), nullptr);
    lru.get("big", 1, Maker{90, "big"}); // alone it fits; b and c go
    EXPECT_EQ(lru.stats().bytes, 90u);
    EXPECT_EQ(lru.stats().entries, 1u);
    lru.get("huge", 1, Maker{150, "huge"}); // over the budget by itself: nothing stays
    EXPECT_EQ(lru.stats().bytes, 0u);
    EXPECT_EQ(lru.stats().evictions, 5u);
    EXPECT_EQ(first->tag, "a");
    lru.get("d", 1, Maker{10, "d"});
    lru.setBudget(LruBudget{.bytes = 0});
    EXPECT_EQ(lru.stats().bytes, 0u);
    EXPECT_EQ(lru.stats().entries, 0u);
}

TEST(VersionedLru, ProducesOncePerEntryAndCountsTheRestAsHits) {
    Lru lru;
    int calls = 0;
    const Lru::Value v = lru.get("a", 3, Maker{1, "x", &calls});
    for (int i = 0; i < 4; ++i) EXPECT_EQ(lru.get("a", 3, Maker{1, "y", &calls}), v);
    EXPECT_EQ(calls, 1);
    EXPECT_EQ(lru.stats().misses, 1u);
    EXPECT_EQ(lru.stats().hits, 4u);
}

// Threads of their own (not TBB tasks) so that on any machine they overlap: the producer holds
// the entry until every thread has asked for it; each gets the one value, made once.
TEST(VersionedLru, ConcurrentCallersJoinTheProductionInFlight) {
    constexpr int kThreads = 8;
    Lru lru;
    std::atomic<int> arrived{0}, calls{0};
    std::vector<Lru::Value> got(kThreads);
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t)
        threads.emplace_back([&, t] {
            ++arrived;
            got[std::size_t(t)] = lru.get("k", 1, [&](const std::optional<Older>&) {
                ++calls;
                while (arrived.load() < kThreads) std::this_thread::yield();
                return std::make_shared<const Blob>(Blob{1, "k"});
            });
        });
    for (auto& t : threads) t.join();
    EXPECT_EQ(calls.load(), 1);
    for (const auto& v : got) EXPECT_EQ(v, got[0]);
    EXPECT_EQ(lru.stats().misses, 1u);
    EXPECT_EQ(lru.stats().hits, std::uint64_t(kThreads - 1));
    EXPECT_EQ(lru.stats().entries, 1u);
}

TEST(VersionedLru, ProducerGetsTheNewestOlderVersionWhichIsDroppedWhenTheNewOneLands) {
    Lru lru;
    request(lru, "a", 2);
    request(lru, "b", 1); // another stable key: never offered for "a"
    std::optional<Older> seen;
    lru.get("a", 5, Maker{1, "a@5", nullptr, &seen});
    ASSERT_TRUE(seen.has_value());
    EXPECT_EQ(seen->version, 2u);
    EXPECT_EQ(seen->value->tag, "a@2");
    EXPECT_EQ(lru.find("a", 2), nullptr) << "superseded";
    EXPECT_NE(lru.find("a", 5), nullptr);
    EXPECT_NE(lru.find("b", 1), nullptr);
    const LruStats s = lru.stats();
    EXPECT_EQ(s.superseded, 1u);
    EXPECT_EQ(s.entries, 2u);
    EXPECT_EQ(s.evictions, 0u);
    // The version produced from the value itself (nothing changed) is the same object, counted
    // once in the bytes.
    const Lru::Value same = lru.get("a", 6, [](const std::optional<Older>& o) { return o->value; });
    EXPECT_EQ(same, lru.find("a", 6));
    EXPECT_EQ(lru.stats().bytes, 2u);
}

TEST(VersionedLru, OnlyListedOlderVersionsAreOffered) {
    Lru lru(LruBudget{.entries = 1});
    std::optional<Older> seen;
    request(lru, "a", 1);
    request(lru, "b", 1); // evicts a@1
    lru.get("a", 2, Maker{1, "a@2", nullptr, &seen});
    EXPECT_FALSE(seen.has_value()) << "an evicted version is not a base";
    lru.setBudget({});
    lru.get("a", 1, Maker{1, "a@1 again", nullptr, &seen});
    EXPECT_FALSE(seen.has_value()) << "a newer version is not a base for an older one";
    EXPECT_EQ(lru.stats().superseded, 0u);
}

TEST(VersionedLru, FailedProductionReachesTheCallerAndIsRetried) {
    Lru lru;
    EXPECT_THROW(
        lru.get("a", 1,
                [](const std::optional<Older>&) -> Lru::Value { throw std::runtime_error("no"); }),
        std::runtime_error);
    EXPECT_EQ(lru.find("a", 1), nullptr);
    EXPECT_EQ(lru.stats().entries, 0u);
    int calls = 0;
    EXPECT_EQ(lru.get("a", 1, Maker{1, "ok", &calls})->tag, "ok");
    EXPECT_EQ(calls, 1);
    EXPECT_EQ(lru.stats().misses, 1u);
    EXPECT_EQ(lru.stats().hits, 1u) << "the retry found the failed entry";
}

// changesSince() names every (key, version) whose contains() answer differs from what it was
// after the count it is given: random requests over a small budget list, evict and supersede
// entries, and each answer that changed between two checkpoints must be among the changes named
// (written out here by asking contains() of every key at each checkpoint). Past the log's length,
// or from a count not reached yet, it cannot tell.
TEST(VersionedLru, ChangesSinceNameEveryEntryWhoseAnswerChanged) {
    Lru lru(LruBudget{.entries = 6});
    std::vector<std::pair<std::string, std::uint64_t>> universe;
    for (int k = 0; k < 12; ++k)
        for (std::uint64_t v = 1; v <= 3; ++v) universe.push_back({"k" + std::to_string(k), v});
    const auto answers = [&] {
        std::vector<bool> a;
        for (const auto& [key, version] : universe) a.push_back(lru.contains(key, version));
        return a;
    };
    std::uint64_t since = lru.changeCount();
    EXPECT_EQ(since, 0u);
    std::vector<bool> before = answers();
    unsigned seed = 12345;
    int changedAnswers = 0;
    for (int round = 0; round < 200; ++round) {
        const int requests = 1 + round % 4;
        for (int r = 0; r < requests; ++r) {
            seed = seed * 1103515245u + 12345u;
            const auto& [key, version] = universe[(seed >> 8) % universe.size()];
            request(lru, key, version); // may list it, evict another, supersede an older one
        }
        std::set<std::pair<std::string, std::uint64_t>> named;
        const std::optional<std::uint64_t> now =
            lru.changesSince(since, [&](const std::string& key, std::uint64_t version) {
                named.insert({key, version});
            });
        ASSERT_TRUE(now.has_value()) << "round " << round;
        EXPECT_EQ(*now, lru.changeCount());
        const std::vector<bool> after = answers();
        for (std::size_t u = 0; u < universe.size(); ++u)
            if (after[u] != before[u]) {
                ++changedAnswers;
                EXPECT_TRUE(named.count(universe[u]))
                    << universe[u].first << "@" << universe[u].second << ", round " << round;
            }
        // Nothing is named that was not listed or dropped: each name is a (key, version) asked.
        for (const auto& n : named)
            EXPECT_NE(std::find(universe.begin(), universe.end(), n), universe.end());
        since = *now, before = after;
    }
    EXPECT_GT(changedAnswers, 200); // the rounds did change answers (lists, evictions, supersedes)
    // Nothing changed since the last count: nothing named, the same count.
    int calls = 0;
    EXPECT_EQ(lru.changesSince(since, [&](const std::string&, std::uint64_t) { ++calls; }), since);
    EXPECT_EQ(calls, 0);
    EXPECT_FALSE(lru.changesSince(since + 1, [](const std::string&, std::uint64_t) {}));
    // More changes than the log keeps: an old count can no longer be answered, a recent one can.
    for (std::size_t k = 0; k < Lru::kChangeLogLength / 2 + 8; ++k)
        request(lru, "w" + std::to_string(k)); // each listed, and another evicted
    EXPECT_FALSE(lru.changesSince(since, [](const std::string&, std::uint64_t) {}));
    const std::uint64_t recent = lru.changeCount();
    request(lru, "last");
    std::vector<std::string> named;
    EXPECT_EQ(lru.changesSince(
                  recent, [&](const std::string& key, std::uint64_t) { named.push_back(key); }),
              recent + 2);
    EXPECT_EQ(named.size(), 2u); // "last" listed and the least recent "w..." evicted
}

} // namespace
} // namespace voxtier
