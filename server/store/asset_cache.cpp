#include "store/asset_cache.h"

#include "store/store.h"

namespace refract::scene {

namespace {

std::string mebibytes(uint64_t bytes) {
    return std::to_string((bytes + (uint64_t{1} << 20) - 1) >> 20) + " MiB";
}

}  // namespace

uint64_t AssetCache::held_bytes() const {
    std::lock_guard lock(mutex_);
    return held_bytes_;
}

void AssetCache::check_fits(const std::string& what, uint64_t bytes) const {
    if (bytes <= budget_) return;
    throw StoreError(StoreFailure::too_large, what + " takes " + mebibytes(bytes) +
                                                  " decoded, more than the daemon's whole budget for "
                                                  "decoded assets (--max-host-memory " +
                                                  mebibytes(budget_) + ")");
}

std::shared_ptr<const void> AssetCache::find_erased(AssetKind kind, const std::string& name, uint64_t version) {
    std::lock_guard lock(mutex_);
    const Key key{kind, name};
    auto it = entries_.find(key);
    if (it == entries_.end() || it->second.version != version) return nullptr;
    Entry& entry = it->second;
    if (entry.held) {
        recent_.splice(recent_.begin(), recent_, entry.recent);
        return entry.held;
    }
    std::shared_ptr<const void> value = entry.alive.lock();
    if (!value) {
        entries_.erase(it);
        return nullptr;
    }
    hold(key, entry, value);
    trim();
    return value;
}

std::shared_ptr<const void> AssetCache::insert_erased(AssetKind kind, const std::string& name, uint64_t version,
                                                      std::shared_ptr<const void> value, uint64_t bytes) {
    std::lock_guard lock(mutex_);
    const Key key{kind, name};
    auto [it, added] = entries_.try_emplace(key);
    Entry& entry = it->second;
    if (!added) {
        if (entry.version > version) return value;
        if (entry.version == version && entry.held) return entry.held;
        if (std::shared_ptr<const void> same = entry.version == version ? entry.alive.lock() : nullptr) {
            hold(key, entry, same);
            trim();
            return same;
        }
        release(entry);
    }
    entry.version = version;
    entry.bytes = bytes;
    entry.alive = value;
    hold(key, entry, value);
    trim();
    return value;
}

void AssetCache::forget(AssetKind kind, const std::string& name) {
    std::lock_guard lock(mutex_);
    auto it = entries_.find({kind, name});
    if (it == entries_.end()) return;
    release(it->second);
    entries_.erase(it);
}

void AssetCache::hold(const Key& key, Entry& entry, std::shared_ptr<const void> value) {
    recent_.push_front(key);
    entry.recent = recent_.begin();
    entry.held = std::move(value);
    held_bytes_ += entry.bytes;
}

void AssetCache::release(Entry& entry) {
    if (!entry.held) return;
    recent_.erase(entry.recent);
    entry.held.reset();
    held_bytes_ -= entry.bytes;
}

void AssetCache::trim() {
    // An asset over the whole budget (stored under a larger one) is decoded for its caller but not held.
    while (held_bytes_ > budget_ && !recent_.empty()) {
        auto it = entries_.find(recent_.back());
        release(it->second);
        if (it->second.alive.expired()) entries_.erase(it);
    }
}

}  // namespace refract::scene
