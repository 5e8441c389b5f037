#pragma once
// A least-recently-used cache of immutable values that come in versions: the shape the snapshot
// cache needs twice (snapshots per view, Embree scenes per model frame; CONTRACT.md §4).
//
// An entry is keyed by (stable key, version). A lookup of a missing entry produces its value
// once however many threads ask meanwhile: the callers that arrive during production join it
// (tbb::collaborative_call_once, so they help with its parallel work instead of idling, and a
// TBB worker never blocks on a bake it should be running). The producer is handed the newest
// listed older version of the same stable key, if any, to derive the new value from (an
// incremental refresh); when the new value lands that older version is dropped, so superseded
// versions never sit in the budget. Listed values are evicted least-recently-used over a byte
// budget, an entry-count budget or both. A value handed out stays valid after eviction.
//
// `T` has `std::size_t bytes() const`. Thread-safe; the producer runs without the lock, so it
// may use other caches (the snapshot producer asks the scene cache for its scene).
#include <tbb/collaborative_call_once.h>

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <unordered_map>
#include <utility>

namespace voxtier {

/// Listed values are evicted (least recently used first) while either limit is exceeded.
struct LruBudget {
    std::size_t bytes = std::numeric_limits<std::size_t>::max();
    std::size_t entries = std::numeric_limits<std::size_t>::max();
};

struct LruStats {
    std::uint64_t hits = 0;       ///< lookups that found their entry (ready, or produced meanwhile)
    std::uint64_t misses = 0;     ///< lookups that created their entry (and produced it)
    std::uint64_t evictions = 0;  ///< listed values dropped for the budget
    std::uint64_t superseded = 0; ///< older versions dropped when the value made from them landed
    std::uint64_t entries = 0;    ///< values listed now
    std::uint64_t bytes = 0;      ///< bytes of the values listed now
};

template <class StableKey, class T, class Hash = std::hash<StableKey>> class VersionedLru {
  public:
    using Value = std::shared_ptr<const T>;
    /// An older version of the same stable key, the base of an incremental refresh.
    struct Older {
        std::uint64_t version;
        Value value;
    };

    explicit VersionedLru(LruBudget budget = {}) : budget_(budget) {}
    VersionedLru(const VersionedLru&) = delete;
    VersionedLru& operator=(const VersionedLru&) = delete;

    /// The value of (key, version): a listed one is returned (and becomes the most recent); one
    /// being produced is joined; otherwise `produce(const std::optional<Older>&)` makes it here,
    /// from the newest listed version of `key` older than `version` when there is one. The new
    /// value is listed, the Older it was handed is dropped (if still there), and the cache
    /// evicts down to its budget. If `produce` throws, the exception reaches this caller and
    /// the next lookup produces again. `produce` is the one place a miss is filled, so a second
    /// source (e.g. a disk cache consulted before baking) belongs inside it.
    template <class Produce>
    Value get(const StableKey& key, std::uint64_t version, Produce&& produce) {
        std::shared_ptr<Entry> e;
        {
            std::lock_guard lock(mutex_);
            std::shared_ptr<Entry>& slot = entries_[key][version];
            if (slot) {
                e = slot;
                ++stats_.hits;
                if (e->listed) lru_.splice(lru_.begin(), lru_, e->lruPos);
                if (e->value) return e->value; // ready; written under mutex_
            } else {
                slot = e = std::make_shared<Entry>();
                ++stats_.misses;
            }
        }
        // Completion of the once orders the write of e->value before the read below.
        tbb::collaborative_call_once(e->once, [&] {
            std::optional<Older> older;
            {
                std::lock_guard lock(mutex_);
                older = olderLocked(key, version);
            }
            Value value = produce(std::as_const(older));
            std::lock_guard lock(mutex_);
            e->value = value;
            if (older && dropLocked({key, older->version})) ++stats_.superseded;
            // Still wanted (not dropped meanwhile, e.g. as someone's superseded version): list it.
            if (entryLocked({key, version}) == e.get()) {
                lru_.push_front({key, version});
                e->lruPos = lru_.begin();
                e->listed = true;
                logChangeLocked({key, version});
                e->bytes = value->bytes();
                stats_.bytes += e->bytes;
                ++stats_.entries;
                evictLocked();
            }
        });
        return e->value;
    }

    /// get() of each (key, version) that `keyAt(i)` gives for i < count whose value is ready,
    /// under one lock and in order: each is returned in out[i], becomes the most recent in turn
    /// and counts as a hit, as in get(). The others (missing, or being produced) are left null
    /// for get(), and not counted here. A frame asking for thousands of listed snapshots takes
    /// the lock once, where a get() apiece had every core queue on it.
    template <class KeyAt> void takeReady(std::size_t count, KeyAt&& keyAt, Value* out) {
        std::lock_guard lock(mutex_);
        for (std::size_t i = 0; i < count; ++i) {
            const auto& [key, version] = keyAt(i);
            const Entry* e = entryLocked({key, version});
            if (!e || !e->value) {
                out[i] = nullptr;
                continue;
            }
            ++stats_.hits;
            if (e->listed) lru_.splice(lru_.begin(), lru_, e->lruPos);
            out[i] = e->value;
        }
    }

    /// Whether (key, version) is listed; as find(), without taking a share of the value (the
    /// planner asks from every core at once, and shares would contend on one count).
    bool contains(const StableKey& key, std::uint64_t version) const {
        std::shared_lock lock(mutex_);
        const Entry* e = entryLocked({key, version});
        return e && e->listed;
    }

    /// The listed value of (key, version) or nullptr; never produces, counts or reorders.
    Value find(const StableKey& key, std::uint64_t version) const {
        std::shared_lock lock(mutex_); // a read: shared
        const Entry* e = entryLocked({key, version});
        return e && e->listed ? e->value : nullptr;
    }

    /// Changes the budget and evicts down to it.
    void setBudget(LruBudget budget) {
        std::lock_guard lock(mutex_);
        budget_ = budget;
        evictLocked();
    }

    LruStats stats() const {
        std::lock_guard lock(mutex_);
        return stats_;
    }

    /// What contains() answers differently now than after the first `since` changes: each
    /// (key, version) listed or unlisted since then (in order; one may appear more than once) is
    /// passed to `changed`, and the count of changes so far is returned (`since` for the next
    /// call). nullopt when the log no longer reaches back that far (it keeps the last
    /// kChangeLogLength), or `since` is later than now. A planner that keeps contains()'s answers
    /// across frames asks again only about these, where a frame's thousands of repeated
    /// questions each took the lock and walked the two maps.
    template <class Changed>
    std::optional<std::uint64_t> changesSince(std::uint64_t since, Changed&& changed) const {
        std::shared_lock lock(mutex_);
        if (since > changes_ || changes_ - since > log_.size()) return std::nullopt;
        for (std::size_t k = log_.size() - std::size_t(changes_ - since); k < log_.size(); ++k)
            changed(std::as_const(log_[k].key), log_[k].version);
        return changes_;
    }
    /// The count of changes of what contains() answers so far (changesSince()'s return).
    std::uint64_t changeCount() const {
        std::shared_lock lock(mutex_);
        return changes_;
    }
    /// The changes changesSince() keeps.
    static constexpr std::size_t kChangeLogLength = std::size_t(1) << 16;

  private:
    struct Slot {
        StableKey key;
        std::uint64_t version;
    };
    struct Entry {
        tbb::collaborative_once_flag once;
        Value value;                               ///< set once, under mutex_
        std::size_t bytes = 0;                     ///< of value, counted while listed
        bool listed = false;                       ///< in lru_ (ready and not evicted); mutex_
        typename std::list<Slot>::iterator lruPos; ///< valid while listed; mutex_
    };
    /// Every version of a stable key that is listed or being produced.
    using Versions = std::map<std::uint64_t, std::shared_ptr<Entry>>;

    // mutex_ held for all of these.
    /// The entry of (key, version), or null; no share taken (readers would contend on its count).
    const Entry* entryLocked(const Slot& s) const {
        const auto k = entries_.find(s.key);
        if (k == entries_.end()) return nullptr;
        const auto v = k->second.find(s.version);
        return v == k->second.end() ? nullptr : v->second.get();
    }

    std::optional<Older> olderLocked(const StableKey& key, std::uint64_t version) const {
        const auto k = entries_.find(key);
        if (k == entries_.end()) return std::nullopt;
        for (auto v = k->second.lower_bound(version); v != k->second.begin();) {
            --v;
            if (v->second->listed) return Older{v->first, v->second->value};
        }
        return std::nullopt;
    }

    /// Forgets (key, version); false if it was not there. By value: callers pass lru_ elements.
    /// Whoever holds the entry or its value keeps it alive (a production in flight included).
    bool dropLocked(const Slot s) {
        const auto k = entries_.find(s.key);
        if (k == entries_.end()) return false;
        const auto v = k->second.find(s.version);
        if (v == k->second.end()) return false;
        Entry& e = *v->second;
        if (e.listed) {
            lru_.erase(e.lruPos);
            e.listed = false;
            logChangeLocked(s);
            stats_.bytes -= e.bytes;
            --stats_.entries;
        }
        k->second.erase(v);
        if (k->second.empty()) entries_.erase(k);
        return true;
    }

    /// (key, version) was listed or unlisted: the newest of the log's kChangeLogLength entries.
    void logChangeLocked(const Slot& s) {
        if (log_.size() == kChangeLogLength) log_.pop_front();
        log_.push_back(s);
        ++changes_;
    }

    void evictLocked() {
        while ((stats_.bytes > budget_.bytes || stats_.entries > budget_.entries) &&
               !lru_.empty()) {
            dropLocked(lru_.back());
            ++stats_.evictions;
        }
    }

    LruBudget budget_;
    mutable std::shared_mutex mutex_;
    std::unordered_map<StableKey, Versions, Hash> entries_;
    std::list<Slot> lru_; ///< listed entries, most recent first
    LruStats stats_;
    std::deque<Slot> log_;      ///< the last changes of `listed`, oldest first
    std::uint64_t changes_ = 0; ///< changes of `listed` ever made
};

} // namespace voxtier
