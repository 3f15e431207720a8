// The process-wide registries under concurrent use, as POV-Ray's parser and render threads
// use them: shared_table from several threads (same and different keys, tables let go
// while others load), the finish-model handle registry (register / addref / get / release
// from several threads while others read), and the lazily computed albedo of a model
// shared by spec. `make sanitize` runs these (Threads.*) under ThreadSanitizer; in the
// ordinary build they check the counts and pointers.
#include <gtest/gtest.h>

#include <atomic>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "shading/finish/finish.h"
#include "shading/brdf/models.h"
#include "shading/tables/table.h"

using namespace shading;

namespace {

constexpr int kThreads = 4;

// One small table built once; loaders hand out copies (building one costs ~2 ms of albedo).
const BrdfTable& prototype() {
    static const std::unique_ptr<BrdfTable> t = [] {
        Lambert l{Rgb(0.5)};
        return build_table(tabulate(l, TableGeometry::isotropic(30.0)), BuildOptions{});
    }();
    return *t;
}

}  // namespace

TEST(Threads, SharedTableFromManyThreads) {
    prototype();
    const SharedTableStats s0 = shared_table_stats();
    std::atomic<int> anchor_loads{0}, loads{0}, wrong{0};
    // The anchor key stays held by this thread: every request for it must be served from memory.
    auto anchor = shared_table("threads-test:anchor", [&] {
        ++anchor_loads;
        return std::make_unique<BrdfTable>(prototype());
    });
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t)
        threads.emplace_back([&, t] {
            std::mt19937 rng(t);
            std::vector<std::shared_ptr<const BrdfTable>> held;
            for (int i = 0; i < 300; ++i) {
                auto a = shared_table("threads-test:anchor", [&] {
                    ++anchor_loads;
                    return std::make_unique<BrdfTable>(prototype());
                });
                if (a.get() != anchor.get()) ++wrong;
                const std::string key = "threads-test:k" + std::to_string(rng() % 3);
                auto b = shared_table(key, [&] {
                    ++loads;
                    return std::make_unique<BrdfTable>(prototype());
                });
                if (!b || b->values() != prototype().values()) ++wrong;
                // Lookups on a shared table while other threads load and free tables.
                if (!(b->eval_iso(0.3, 0.4, 1.0).r > 0)) ++wrong;
                if (rng() % 2) held.push_back(std::move(b));
                if (held.size() > 3) held.erase(held.begin() + long(rng() % held.size()));
                if (i % 50 == 0) (void)shared_table_stats();
            }
        });
    for (auto& th : threads) th.join();
    EXPECT_EQ(wrong.load(), 0);
    EXPECT_EQ(anchor_loads.load(), 1);
    EXPECT_GE(loads.load(), 3);
    const SharedTableStats s1 = shared_table_stats();
    EXPECT_EQ(s1.live_tables, s0.live_tables + 1);  // only the anchor is still held
    EXPECT_EQ(s1.live_bytes, s0.live_bytes + anchor->bytes_used());
    anchor.reset();
    EXPECT_EQ(shared_table_stats().live_tables, s0.live_tables);
    EXPECT_EQ(shared_table_stats().live_bytes, s0.live_bytes);
}

TEST(Threads, FinishRegistryFromManyThreads) {
    const std::size_t live0 = finish_model_live_count();
    auto model = std::make_shared<FinishModel>();
    model->brdf = std::make_shared<Lambert>(Rgb(0.25));
    // A handle held throughout: readers must always see it, whatever the others do.
    const int fixed = finish_model_register(model);
    std::atomic<int> wrong{0};
    std::atomic<bool> stop{false};
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t)
        threads.emplace_back([&, t] {
            std::mt19937 rng(100 + t);
            std::vector<std::pair<int, const FinishModel*>> mine;
            for (int i = 0; i < 2000; ++i) {
                auto m = std::make_shared<FinishModel>();
                m->brdf = model->brdf;
                const int h = finish_model_register(m);
                finish_model_addref(h);  // a copied FINISH
                mine.emplace_back(h, m.get());
                for (const auto& [handle, ptr] : mine)
                    if (finish_model_get(handle) != ptr) ++wrong;
                if (finish_model_get(fixed) != model.get()) ++wrong;
                if (mine.size() > 8 || rng() % 3 == 0) {  // both references go, in any order
                    const size_t k = rng() % mine.size();
                    finish_model_release(mine[k].first);
                    finish_model_release(mine[k].first);
                    mine.erase(mine.begin() + long(k));
                }
            }
            for (const auto& [handle, ptr] : mine) {
                finish_model_release(handle);
                finish_model_release(handle);
            }
        });
    // A render thread: lock-free lookups of the held handle while the parsers work.
    std::thread reader([&] {
        while (!stop.load(std::memory_order_relaxed)) {
            const FinishModel* m = finish_model_get(fixed);
            if (m != model.get() || m->brdf->f(Vec3(0, 0, 1), Vec3(0, 0, 1)).r <= 0) ++wrong;
        }
    });
    for (auto& th : threads) th.join();
    stop = true;
    reader.join();
    EXPECT_EQ(wrong.load(), 0);
    EXPECT_EQ(finish_model_live_count(), live0 + 1);
    finish_model_release(fixed);
    EXPECT_EQ(finish_model_get(fixed), nullptr);
    EXPECT_EQ(finish_model_live_count(), live0);
}

TEST(Threads, AlbedoOfASpecFromManyThreads) {
    const std::string spec = "lambert rho=0.375";
    std::vector<std::shared_ptr<FinishModel>> models(kThreads);
    std::vector<Rgb> albedo(kThreads);
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t)
        threads.emplace_back([&, t] {
            models[t] = make_finish_model_from_spec(spec);
            albedo[t] = finish_model_albedo(*models[t], 0.5);
        });
    for (auto& th : threads) th.join();
    // Threads that ask for a new spec at the same moment may each build it (the memo is
    // filled after the build, outside its lock; POV-Ray parses on one thread), but every
    // model gets the same albedo, and a later request shares one of the BRDFs built.
    for (int t = 0; t < kThreads; ++t) {
        EXPECT_EQ(albedo[t].r, albedo[0].r) << t;
        EXPECT_NEAR(albedo[t].r, 0.375, 1e-3) << t;
    }
    auto later = make_finish_model_from_spec(spec);
    bool shared = false;
    for (int t = 0; t < kThreads; ++t) shared = shared || later->brdf.get() == models[t]->brdf.get();
    EXPECT_TRUE(shared);
}
