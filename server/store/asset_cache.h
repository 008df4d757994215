// Decoded assets (meshes, index grids, environment maps) held within a byte budget of host memory: the
// stores keep only the compact bytes as uploaded (files or rows) and decode on demand through here. The
// least recently used are dropped first and decoded again when next asked for. Thread-safe.
#pragma once

#include <cstdint>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

namespace refract::scene {

// Volumes are kept as uploaded and never decoded here until something renders them.
enum class AssetKind { mesh, grid, environment, volume };

class AssetCache {
public:
    explicit AssetCache(uint64_t budget_bytes) : budget_(budget_bytes) {}

    uint64_t budget() const { return budget_; }
    // Bytes held now by the cache itself (not counting dropped assets someone still holds).
    uint64_t held_bytes() const;

    // Throws StoreError(too_large) when an asset of `bytes` could never be held: the whole budget is
    // smaller.
    void check_fits(const std::string& what, uint64_t bytes) const;

    // The asset decoded from `version` of (kind, name), or nullptr. One that was dropped but is still held
    // elsewhere (the renderer's resident scenes) comes back as the same pointer: a new pointer would tell
    // the renderer it changed.
    template <typename T>
    std::shared_ptr<const T> find(AssetKind kind, const std::string& name, uint64_t version) {
        return std::static_pointer_cast<const T>(find_erased(kind, name, version));
    }

    // Holds `value`, decoded from `version` of (kind, name) and taking `bytes`, dropping the least recently
    // used past the budget; returns the pointer to use, which is the one already held when another thread
    // decoded the same version first. A value older than the one held is returned but not held.
    template <typename T>
    std::shared_ptr<const T> insert(AssetKind kind, const std::string& name, uint64_t version,
                                    std::shared_ptr<const T> value, uint64_t bytes) {
        return std::static_pointer_cast<const T>(insert_erased(kind, name, version, std::move(value), bytes));
    }

    // Drops (kind, name) whatever its version: deleted, or changed by another replica.
    void forget(AssetKind kind, const std::string& name);

private:
    using Key = std::pair<AssetKind, std::string>;
    struct Entry {
        uint64_t version = 0;
        uint64_t bytes = 0;
        std::shared_ptr<const void> held;  // null once dropped
        std::weak_ptr<const void> alive;   // while anyone holds it
        std::list<Key>::iterator recent;   // its place in recent_, while held
    };

    std::shared_ptr<const void> find_erased(AssetKind kind, const std::string& name, uint64_t version);
    std::shared_ptr<const void> insert_erased(AssetKind kind, const std::string& name, uint64_t version,
                                              std::shared_ptr<const void> value, uint64_t bytes);
    // Holds `entry` again (or for the first time) as the most recently used. Caller holds mutex_.
    void hold(const Key& key, Entry& entry, std::shared_ptr<const void> value);
    void release(Entry& entry);
    void trim();

    const uint64_t budget_;
    mutable std::mutex mutex_;
    std::map<Key, Entry> entries_;
    std::list<Key> recent_;  // held entries, most recently used first
    uint64_t held_bytes_ = 0;
};

}  // namespace refract::scene
