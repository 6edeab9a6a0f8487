// Subtrees built apart (on their own threads) and joined into the depth-first node array, shared
// by the binned and sweep builders.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <vector>

#include "kiln/formats/bvh.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

// Appends `sub` (a subtree emitted on its own, indices from 0) to `nodes`, shifting its interior
// nodes' second-child indices; leaf offsets index the shared reference order and stay.
inline void append_bvh_subtree(std::vector<format::BvhNode>& nodes,
                               const std::vector<format::BvhNode>& sub) {
  const auto shift = std::uint32_t(nodes.size());
  for (format::BvhNode n : sub) {
    if (n.count == 0) n.offset += shift;
    nodes.push_back(n);
  }
}

/// What a builder counts over a subtree built apart (its nodes in order), or empty.
using CountApart = std::function<void(const std::vector<format::BvhNode>&)>;

/// Appends `sub` as append_bvh_subtree does and, beside it (on another thread when one is free:
/// at the root's join the other one has nothing left to do), `count(sub)`.
inline void append_bvh_subtree_counting(std::vector<format::BvhNode>& nodes,
                                        const std::vector<format::BvhNode>& sub,
                                        const CountApart& count) {
  fork_join(
      count && sub.size() >= 16384, [&] { append_bvh_subtree(nodes, sub); },
      [&] {
        if (count) count(sub);
      });
}

/// Worker slots for recursive builders that fork on demand: a subtree goes to a new thread when
/// a slot is free, whatever its depth, so an uneven split near the root does not leave a core
/// idle (the fixed fork depth did). A thread waiting on its forked half gives its slot back
/// meanwhile. Where a subtree runs never changes the nodes (emit_bvh_children appends in order).
class WorkerSlots {
 public:
  explicit WorkerSlots(unsigned workers) : free_(int(workers) - 1) {}
  /// Takes a slot for a new thread, if one is free.
  bool try_take() {
    int f = free_.load(std::memory_order_relaxed);
    while (f > 0 && !free_.compare_exchange_weak(f, f - 1)) {
    }
    return f > 0;
  }
  /// Takes every free slot (for a parallel loop); returns how many.
  unsigned take_all() {
    int f = free_.load(std::memory_order_relaxed);
    while (f > 0 && !free_.compare_exchange_weak(f, 0)) {
    }
    return unsigned(std::max(f, 0));
  }
  void give(unsigned n = 1) { free_ += int(n); }
  /// A running thread blocks (gives its slot) or resumes (takes one back, even if none is free:
  /// the count may go below zero until a thread ends).
  void block() { free_ += 1; }
  void resume() { free_ -= 1; }

 private:
  std::atomic<int> free_;
};

/// The fork of the builders that take a slot first (`slots.try_take()` succeeded): `forked` runs
/// as a task that gives the slot back when it ends, `here` on this thread, which then waits for
/// it with its own slot given back meanwhile. Rethrows `here`'s exception, else `forked`'s; the
/// slots balance either way.
template <class Here, class Forked>
void fork_on_slot(WorkerSlots& slots, const Here& here, const Forked& forked) {
  struct Give {
    WorkerSlots& slots;
    ~Give() { slots.give(); }
  };
  auto body = [&] {
    const Give give{slots};
    forked();
  };
  ForkedTask task(body);
  here();  // if it throws, the task joins on unwinding
  slots.block();
  struct Resume {
    WorkerSlots& slots;
    ~Resume() { slots.resume(); }
  } const resume{slots};
  task.join();
}

/// Right children that their thread will emit after the left one, listed while it does so: a
/// forked thread that has finished its own subtree takes the largest (and builds it apart)
/// before it ends, so a free core need not wait for the next split that may fork. The owner
/// appends a taken one (waiting for it if need be) where it would have emitted it: the nodes
/// are the same wherever a subtree is built. `Out`: what a subtree is emitted into.
template <class Out>
class PendingRightsOf {
 public:
  struct Entry {
    std::size_t size = 0;
    std::function<void(Out&)> build;
    Out nodes;
    std::exception_ptr error;
    bool done = false;
  };
  void add(Entry* e) {
    {
      const std::lock_guard lock(mutex_);
      list_.push_back(e);
    }
    done_.notify_all();  // an owner waiting in reclaim may build it
  }
  /// The owner takes `e` back: true if no thread took it, else false once it is built. While
  /// another thread builds it, the owner builds listed entries (the largest first) rather than
  /// wait idle: at the end of a build, the thread that took the last large subtree lists its
  /// right children as it goes, and the owner takes them.
  bool reclaim(Entry* e, WorkerSlots& slots) {
    std::unique_lock lock(mutex_);
    if (const auto it = std::find(list_.begin(), list_.end(), e); it != list_.end()) {
      list_.erase(it);
      return true;
    }
    while (!e->done) {
      if (!list_.empty()) {
        lock.unlock();
        build_one();
        lock.lock();
        continue;
      }
      slots.block();
      done_.wait(lock, [&] { return e->done || !list_.empty(); });
      slots.resume();
    }
    return false;
  }
  /// Builds the largest listed entry on this thread; false when none is listed.
  bool build_one() {
    Entry* e = nullptr;
    {
      const std::lock_guard lock(mutex_);
      if (list_.empty()) return false;
      const auto it = std::max_element(list_.begin(), list_.end(),
                                       [](Entry* a, Entry* b) { return a->size < b->size; });
      e = *it;
      list_.erase(it);
    }
    try {
      e->build(e->nodes);
    } catch (...) {
      e->error = std::current_exception();
    }
    {
      const std::lock_guard lock(mutex_);
      e->done = true;
    }
    done_.notify_all();
    return true;
  }

 private:
  std::mutex mutex_;
  std::condition_variable done_;
  std::vector<Entry*> list_;
};

/// The binned builder's: subtrees as nodes alone (leaf offsets index the shared references).
using PendingRights = PendingRightsOf<std::vector<format::BvhNode>>;

/// Emits a node's two children after it, in turn, with `emit(child, nodes)`; returns where the
/// second one starts.
template <class Child, class Emit>
std::uint32_t emit_bvh_children_in_turn(const Child& left, const Child& right,
                                        std::vector<format::BvhNode>& nodes, const Emit& emit) {
  emit(left, nodes);
  const auto second = std::uint32_t(nodes.size());
  emit(right, nodes);
  return second;
}

/// How many nodes `nodes` holds (emit_children_scheduled's position of a right child).
inline std::size_t emitted_nodes(const std::vector<format::BvhNode>& nodes) {
  return nodes.size();
}

/// The schedule of the recursive builders (binned, SBVH) for a node's two children: the right one
/// on a new thread when `may_fork` and `slots` has one free (that thread, done with it, builds
/// listed ones); else, with `pending` (and `may_fork`), listed while the left one is emitted, for
/// a thread with nothing to do, and emitted here if none took it; else in turn. `emit_left(o)`
/// and `emit_right(o)` emit into `o`: `out`, or for a right subtree built apart a fresh Out
/// (reserved for `right_size` nodes where Out can reserve) that `append(out, sub)` then appends.
/// Every way gives the same `out`. Returns where the right child starts (emitted_nodes(out)).
template <class Out, class EmitLeft, class EmitRight, class Append>
std::uint32_t emit_children_scheduled(WorkerSlots& slots, bool may_fork,
                                      PendingRightsOf<Out>* pending, std::size_t right_size,
                                      Out& out, const EmitLeft& emit_left,
                                      const EmitRight& emit_right, const Append& append) {
  const auto emit_apart = [&](Out& sub) {
    if constexpr (requires { sub.reserve(right_size); }) sub.reserve(right_size);
    emit_right(sub);
  };
  if (may_fork && slots.try_take()) {
    Out sub;
    fork_on_slot(
        slots, [&] { emit_left(out); },
        [&] {
          emit_apart(sub);
          while (pending && pending->build_one()) {
          }
        });
    const auto second = std::uint32_t(emitted_nodes(out));
    append(out, sub);
    return second;
  }
  if (may_fork && pending) {
    typename PendingRightsOf<Out>::Entry entry;
    entry.size = right_size;
    entry.build = emit_apart;
    pending->add(&entry);
    try {
      emit_left(out);
    } catch (...) {
      pending->reclaim(&entry, slots);  // a thread building it refers to this frame: wait
      throw;
    }
    const auto second = std::uint32_t(emitted_nodes(out));
    if (pending->reclaim(&entry, slots)) {
      emit_right(out);
    } else {
      if (entry.error) std::rethrow_exception(entry.error);
      append(out, entry.nodes);
    }
    return second;
  }
  emit_left(out);
  const auto second = std::uint32_t(emitted_nodes(out));
  emit_right(out);
  return second;
}

/// Emits a node's two children after it with `emit(child, nodes)` by emit_children_scheduled
/// (`may_fork`: the caller's size rule; `reserve` nodes reserved for a right subtree built apart);
/// `count_apart`, if any, counts a subtree built apart beside its append. Links the node at
/// `index` to its second child and makes it interior.
template <class Child, class Emit>
void emit_bvh_children_on_demand(WorkerSlots& slots, bool may_fork, const Child& left,
                                 const Child& right, std::size_t reserve, std::size_t index,
                                 std::vector<format::BvhNode>& nodes, const Emit& emit,
                                 PendingRights* pending = nullptr,
                                 const CountApart& count_apart = {}) {
  const std::uint32_t second = emit_children_scheduled(
      slots, may_fork, pending, reserve, nodes, [&](auto& o) { emit(left, o); },
      [&](auto& o) { emit(right, o); },
      [&](auto& o, const auto& sub) { append_bvh_subtree_counting(o, sub, count_apart); });
  nodes[index].offset = second;
  nodes[index].count = 0;
}

// Emits a node's two children after it with `emit(child, nodes)`: in turn, or (with `fork`)
// apart, the right one on its own thread, then appended in order, so the nodes are the same
// either way. Links the node at `index` to its second child and makes it interior.
template <class Child, class Emit>
void emit_bvh_children(bool fork, const Child& left, const Child& right, std::size_t index,
                       std::vector<format::BvhNode>& nodes, const Emit& emit) {
  std::uint32_t second;
  if (fork) {
    std::vector<format::BvhNode> l, r;
    fork_join(
        true, [&] { emit(left, l); }, [&] { emit(right, r); });
    nodes.reserve(nodes.size() + l.size() + r.size());
    append_bvh_subtree(nodes, l);
    second = std::uint32_t(nodes.size());
    append_bvh_subtree(nodes, r);
  } else {
    second = emit_bvh_children_in_turn(left, right, nodes, emit);
  }
  nodes[index].offset = second;
  nodes[index].count = 0;
}

}  // namespace kiln
