#include "src/core/interrupt_cleanup.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstring>

namespace nimbus::interrupt_cleanup {
namespace {

struct Entry {
    char path[kMaxPathBytes];
    bool folder;
};

Entry g_entries[kMaxPaths];
// Entries [0, g_count) are complete: an entry is written before the count that publishes it
// (release), and the handler, on whichever thread the signal lands (MPI's helper threads
// included), reads the count first (acquire).
std::atomic<int> g_count{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs a lock-free count");

constexpr int kSignals[] = {SIGINT, SIGTERM, SIGHUP};

// Set while a Deferred exists: the handler then only notes the signal, raised again after.
std::atomic<int> g_deferring{0}, g_pending{0};
// Set by the first handler that ends the process. A signal often comes twice at once (timeout(1)
// sends it to the command and then to its process group; mpiexec passes one on): a second one,
// landing on another thread while the first cleans up, must not end the process half-way.
std::atomic<int> g_ending{0};
std::atomic<int> g_speaks{0};  // this process reports the cleanup on stderr
std::atomic<int> g_committed{0};  // the run's outputs are in place (committed())
static_assert(std::atomic<int>::is_always_lock_free);

bool add(const std::string& path, bool folder) {
    const int n = g_count.load(std::memory_order_relaxed);
    if (n >= kMaxPaths || path.empty() || path.size() >= static_cast<size_t>(kMaxPathBytes)) return false;
    std::memcpy(g_entries[n].path, path.c_str(), path.size() + 1);
    g_entries[n].folder = folder;
    g_count.store(n + 1, std::memory_order_release);
    return true;
}

void remove_all() {
    const int n = g_count.load(std::memory_order_acquire);
    for (int i = n - 1; i >= 0; --i)
        if (!g_entries[i].folder) ::unlink(g_entries[i].path);
    for (int i = n - 1; i >= 0; --i)  // latest (innermost) first; a folder with files stays
        if (g_entries[i].folder) ::rmdir(g_entries[i].path);
    if (g_speaks.load(std::memory_order_relaxed) == 0) return;  // rank 0 says what happened
    static const char kRemoved[] = "nimbus: interrupted: removed this run's temporary files and new folders\n";
    static const char kNothing[] = "nimbus: interrupted before writing any output: the output folder is as it was\n";
    static const char kDone[] = "nimbus: interrupted after this run's outputs were written: they are complete\n";
    const char* text = g_committed.load(std::memory_order_acquire) ? kDone : n > 0 ? kRemoved : kNothing;
    [[maybe_unused]] const ssize_t w = ::write(STDERR_FILENO, text, std::strlen(text));
}

// Cleans up, then ends the process by `sig` (its exit status says which): the default action
// again, and the signal raised (inside the handler it is blocked until the handler returns).
// Only the first caller does it; any other returns at once and the first one ends the process.
void end_by(int sig) {
    if (g_ending.exchange(1, std::memory_order_acq_rel)) return;
    remove_all();
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    sigemptyset(&dfl.sa_mask);
    ::sigaction(sig, &dfl, nullptr);
    ::raise(sig);
}

extern "C" void on_signal(int sig) {
    if (g_deferring.load(std::memory_order_acquire)) {
        g_pending.store(sig, std::memory_order_release);
        return;
    }
    end_by(sig);
}

}  // namespace

void install(bool speaks) {
    g_speaks.store(speaks ? 1 : 0, std::memory_order_relaxed);
    for (int sig : kSignals) {
        struct sigaction old {};
        // A signal the process was started with ignored stays ignored (nohup's SIGHUP, the
        // SIGINT of a background job of a non-interactive shell): the user chose that.
        if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
        struct sigaction sa {};
        sa.sa_handler = on_signal;
        sigemptyset(&sa.sa_mask);
        for (int other : kSignals) sigaddset(&sa.sa_mask, other);  // one cleanup at a time
        sa.sa_flags = 0;  // not SA_RESETHAND: a second signal on another thread would kill at once
        ::sigaction(sig, &sa, nullptr);
    }
}

bool add_file(const std::string& path) { return add(path, false); }
bool add_folder(const std::string& path) { return add(path, true); }

void clear() {
    g_count.store(0, std::memory_order_release);
    g_committed.store(0, std::memory_order_release);
}

void committed() {  // the flag first: a signal in between says "complete", which is then true
    g_committed.store(1, std::memory_order_release);
    g_count.store(0, std::memory_order_release);
}

// A signal process-directed (kill, mpiexec) may land on any thread, so masking this one would
// not hold it back: the handler checks the flag instead.
Deferred::Deferred() { g_deferring.store(1, std::memory_order_release); }

Deferred::~Deferred() {
    g_deferring.store(0, std::memory_order_release);
    // A signal came meanwhile: this ends the process by it, with whatever is still registered
    // removed first.
    if (const int sig = g_pending.exchange(0)) end_by(sig);
}

}  // namespace nimbus::interrupt_cleanup
