// TableRegistry: see registry.h for the handle scheme and the locking rules.
#include "shading/registry.h"

namespace shading {

namespace {
constexpr uint32_t kGenerationMask = 0x7fff;  // handle = gen << 16 | (slot + 1) stays a positive int
}

TableRegistry::TableRegistry(uint32_t capacity) : capacity_(capacity), slots_(new Slot[capacity]) {
    if (capacity < 1 || capacity > kMaxCapacity) throw std::invalid_argument("TableRegistry: capacity in [1, 65535]");
}

TableRegistry::~TableRegistry() = default;

TableRegistry& TableRegistry::global() {
    // Leaked on purpose: finishes destroyed during static destruction may still release.
    static TableRegistry* r = new TableRegistry();
    return *r;
}

int TableRegistry::handle_of(uint32_t slot) const {
    uint32_t gen = slots_[slot].generation.load(std::memory_order_relaxed) & kGenerationMask;
    return int(gen << 16 | (slot + 1));
}

TableRegistry::Slot* TableRegistry::slot_of(int handle) const noexcept {
    if (handle <= 0) return nullptr;
    uint32_t h = uint32_t(handle), slot = (h & 0xffff) - 1, gen = h >> 16;
    if ((h & 0xffff) == 0 || slot >= capacity_) return nullptr;
    Slot& s = slots_[slot];
    if ((s.generation.load(std::memory_order_acquire) & kGenerationMask) != gen) return nullptr;
    return &s;
}

const BrdfTable* TableRegistry::get(int handle) const noexcept {
    Slot* s = slot_of(handle);
    return s ? s->table.load(std::memory_order_acquire) : nullptr;
}

int TableRegistry::acquire_existing(const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = by_key_.find(key);
    if (it == by_key_.end()) return 0;
    ++slots_[it->second].refs;
    return handle_of(it->second);
}

int TableRegistry::acquire(const std::string& key, const Loader& load) {
    if (int h = acquire_existing(key)) return h;
    std::unique_ptr<BrdfTable> table = load();
    if (!table) throw TableError(key + ": loader returned no table");
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = by_key_.find(key);
    if (it != by_key_.end()) {  // another thread registered it while we loaded: use theirs
        ++slots_[it->second].refs;
        return handle_of(it->second);
    }
    for (uint32_t k = 0; k < capacity_; ++k) {
        Slot& s = slots_[k];
        if (s.owner) continue;
        s.refs = 1;
        s.key = key;
        total_bytes_.fetch_add(table->bytes_used(), std::memory_order_relaxed);
        s.owner = std::move(table);
        s.table.store(s.owner.get(), std::memory_order_release);
        by_key_.emplace(key, k);
        ++live_;
        return handle_of(k);
    }
    throw TableError(key + ": offset 0: expected a free BRDF table registry slot, found all " +
                     std::to_string(capacity_) + " in use");
}

bool TableRegistry::addref(int handle) {
    std::lock_guard<std::mutex> lock(mutex_);
    Slot* s = slot_of(handle);
    if (!s || !s->owner) return false;
    ++s->refs;
    return true;
}

bool TableRegistry::release(int handle) {
    std::unique_ptr<BrdfTable> doomed;  // freed after the lock is dropped
    {
        std::lock_guard<std::mutex> lock(mutex_);
        Slot* s = slot_of(handle);
        if (!s || !s->owner) return false;
        if (--s->refs > 0) return true;
        s->table.store(nullptr, std::memory_order_release);
        // A new generation makes stale copies of this handle read nullptr.
        uint32_t g = s->generation.load(std::memory_order_relaxed) + 1;
        if ((g & kGenerationMask) == 0) ++g;
        s->generation.store(g, std::memory_order_release);
        total_bytes_.fetch_sub(s->owner->bytes_used(), std::memory_order_relaxed);
        by_key_.erase(s->key);
        s->key.clear();
        doomed = std::move(s->owner);
        --live_;
    }
    return true;
}

int TableRegistry::refcount(int handle) const {
    std::lock_guard<std::mutex> lock(mutex_);
    Slot* s = slot_of(handle);
    return s && s->owner ? s->refs : 0;
}

size_t TableRegistry::size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return live_;
}

}  // namespace shading
