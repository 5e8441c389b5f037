#pragma once
// Per-entity arrays a renderer keeps between frames and hands out with each frame's result
// (the sprites, the plan): a frame's result shares the renderer's array instead of copying it,
// so a frame of 100,000 entities hands out its 64 MB of sprites for nothing. The renderer writes
// through SharedVectorOwner::writable(), which copies the array first only while some earlier
// result still holds it (copy on write): a result stays what its frame drew, whatever the
// renderer does next, and a caller that drops each result before the next frame never pays a copy.
#include <algorithm>
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
        if (data_.use_count() > 1) data_ = std::make_shared<std::vector<T>>(*data_);
        return *data_;
    }
    /// The array to fill anew: a new, empty one if a share of it is still held (nothing
    /// copied), else this one, emptied.
    std::vector<T>& fresh() {
        if (data_.use_count() > 1) data_ = std::make_shared<std::vector<T>>();
        data_->clear();
        return *data_;
    }
    const std::vector<T>& read() const { return *data_; }
    SharedVector<T> share() const { return SharedVector<T>(data_); }

  private:
    std::shared_ptr<std::vector<T>> data_;
};

} // namespace voxtier
