#pragma once
// Per-entity arrays a renderer keeps between frames and hands out with each frame's result
// (the sprites, the plan): a frame's result shares the renderer's array instead of copying it,
// so a frame of 100,000 entities hands out its 64 MB of sprites for nothing. The renderer writes
// through SharedVectorOwner::writable(), which copies the array first only while some earlier
// result still holds it (copy on write): a result stays what its frame drew, whatever the
// renderer does next, and a caller that drops each result before the next frame never pays a copy.
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <memory>
#include <span>
#include <vector>

namespace voxtier {

/// A read-only share of a per-entity array (empty by default).
template <class T> class SharedVector {
  public:
    SharedVector() = default;
    explicit SharedVector(std::shared_ptr<const std::vector<T>> data) : data_(std::move(data)) {}

    std::size_t size() const { return data_ ? data_->size() : 0; }
    bool empty() const { return size() == 0; }
    const T& operator[](std::size_t i) const { return (*data_)[i]; }
    const T* begin() const { return data_ ? data_->data() : nullptr; }
    const T* end() const { return begin() + size(); }
    std::span<const T> span() const { return {begin(), size()}; }
    operator std::span<const T>() const { return span(); }
    /// A copy the caller owns.
    std::vector<T> copy() const { return {begin(), end()}; }
    bool operator==(const SharedVector& o) const {
        return size() == o.size() && std::equal(begin(), end(), o.begin());
    }

  private:
    std::shared_ptr<const std::vector<T>> data_;
};

/// The writer's side: the array, and shares of it.
template <class T> class SharedVectorOwner {
  public:
    SharedVectorOwner() : data_(std::make_shared<std::vector<T>>()) {}

    /// The array to write to: copied first if a share of it is still held elsewhere.
    std::vector<T>& writable() {
        if (data_.use_count() > 1) {
            std::shared_ptr<std::vector<T>> next = unheld();
            *next = *data_; // into the kept capacity
            data_ = std::move(next);
        }
        return *data_;
    }
    /// The array to fill anew: another, empty one if a share of it is still held (nothing
    /// copied), else this one, emptied.
    std::vector<T>& fresh() {
        if (data_.use_count() > 1) data_ = unheld();
        data_->clear();
        return *data_;
    }
    /// The array to overwrite whole, `n` elements long: another one if a share of it is still
    /// held, holding whatever it held (nothing copied, nothing cleared), else this one. For a
    /// caller that writes every element (a plan of 100,000 moving entities: fresh() and an assign
    /// wrote its 3.6 MB once more, writable() copied them, on one core either way).
    std::vector<T>& overwritable(std::size_t n) {
        if (data_.use_count() > 1) data_ = unheld();
        if (data_->size() != n) data_->resize(n);
        return *data_;
    }
    const std::vector<T>& read() const { return *data_; }
    SharedVector<T> share() const { return SharedVector<T>(data_); }

  private:
    /// An array that no share holds, for writing in place of the held one, which is kept: with a
    /// frame or two in flight each holding one, the arrays they drop come back here with their
    /// capacity, and a frame allocates nothing (100,000 entities' plans: 3.6 MB, its page faults
    /// and the kernel's zeroing, every frame). Arrays held longer are let go past kKept.
    std::shared_ptr<std::vector<T>> unheld() {
        std::shared_ptr<std::vector<T>> found;
        for (auto it = kept_.begin(); it != kept_.end(); ++it)
            if (it->use_count() == 1) {
                found = std::move(*it);
                kept_.erase(it);
                // The last share was dropped by a release decrement, maybe on another thread: its
                // reads of the array happen before the writes that follow.
                std::atomic_thread_fence(std::memory_order_acquire);
                break;
            }
        kept_.push_back(data_);
        if (kept_.size() > kKept) kept_.erase(kept_.begin());
        return found ? found : std::make_shared<std::vector<T>>();
    }
    static constexpr std::size_t kKept = 3;

    std::shared_ptr<std::vector<T>> data_;
    std::vector<std::shared_ptr<std::vector<T>>> kept_; ///< held elsewhere when last written
};

} // namespace voxtier
