// Process-wide, reference-counted registry of loaded BRDF tables.
//
// POV-Ray's FINISH is a plain C struct copied with `*New = *Old`, so it holds only an int
// handle: the parser calls acquire() once per `brdf_table "file"`, Copy_Finish calls
// addref(), Destroy_Finish calls release(), and the renderer calls get() per shading
// sample. Tables are keyed by the resolved path, so two finishes naming the same file
// share one table.
//
// Concurrency: acquire/addref/release take a mutex; get() is lock-free and wait-free: the
// slots live in one array allocated at construction (never reallocated), and a handle
// indexes it directly, reading an atomic pointer. A handle is (generation << 16) | (slot+1),
// so a handle used after its table was freed and the slot reused returns nullptr instead
// of another table (best effort: using a released handle is a caller bug). The table a
// handle names stays alive while the caller holds a reference; tables are immutable, so
// any number of threads may use the pointer get() returns.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>

#include "shading/table.h"

namespace shading {

class TableRegistry {
public:
    static constexpr uint32_t kDefaultCapacity = 1024;
    static constexpr uint32_t kMaxCapacity = 65535;  // slot index lives in 16 bits

    explicit TableRegistry(uint32_t capacity = kDefaultCapacity);
    ~TableRegistry();
    TableRegistry(const TableRegistry&) = delete;
    TableRegistry& operator=(const TableRegistry&) = delete;

    // The registry POV-Ray uses (constructed on first use, never destroyed before exit).
    static TableRegistry& global();

    using Loader = std::function<std::unique_ptr<BrdfTable>()>;
    // Handle (> 0) to the table under `key`, its count incremented. If absent, `load` is
    // called (outside the lock, so it may be slow or re-enter the registry); if two threads
    // load the same key at once, one result is kept and the other discarded. Exceptions
    // from `load` propagate and register nothing. Throws TableError when every slot is used.
    int acquire(const std::string& key, const Loader& load);
    // Handle of a registered key, its count incremented; 0 if absent.
    int acquire_existing(const std::string& key);

    const BrdfTable* get(int handle) const noexcept;  // nullptr for 0, bad or stale handles
    bool addref(int handle);   // false (and nothing done) for 0 or a bad handle
    bool release(int handle);  // frees the table when the count reaches 0
    int refcount(int handle) const;

    size_t total_bytes() const noexcept { return total_bytes_.load(std::memory_order_relaxed); }
    size_t size() const;  // live tables
    uint32_t capacity() const { return capacity_; }

private:
    struct Slot {
        std::atomic<const BrdfTable*> table{nullptr};
        std::atomic<uint32_t> generation{1};
        int refs = 0;  // guarded by mutex_
        std::unique_ptr<BrdfTable> owner;
        std::string key;
    };
    Slot* slot_of(int handle) const noexcept;  // checks range and generation
    int handle_of(uint32_t slot) const;

    const uint32_t capacity_;
    std::unique_ptr<Slot[]> slots_;
    mutable std::mutex mutex_;
    std::unordered_map<std::string, uint32_t> by_key_;
    uint32_t live_ = 0;
    std::atomic<size_t> total_bytes_{0};
};

}  // namespace shading
