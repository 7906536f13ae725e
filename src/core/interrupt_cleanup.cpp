#include "src/core/interrupt_cleanup.h"

#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstring>

namespace nimbus::interrupt_cleanup {
namespace {

struct Entry {
    char path[kMaxPathBytes];
    bool folder;
};

Entry g_entries[kMaxPaths];
// Entries [0, g_count) are complete: an entry is written before the count that publishes it.
volatile std::sig_atomic_t g_count = 0;

bool add(const std::string& path, bool folder) {
    const int n = g_count;
    if (n >= kMaxPaths || path.empty() || path.size() >= static_cast<size_t>(kMaxPathBytes)) return false;
    std::memcpy(g_entries[n].path, path.c_str(), path.size() + 1);
    g_entries[n].folder = folder;
    std::atomic_signal_fence(std::memory_order_release);
    g_count = n + 1;
    return true;
}

void remove_all() {
    const int n = g_count;
    std::atomic_signal_fence(std::memory_order_acquire);
    for (int i = n - 1; i >= 0; --i)
        if (!g_entries[i].folder) ::unlink(g_entries[i].path);
    for (int i = n - 1; i >= 0; --i)  // latest (innermost) first; a folder with files stays
        if (g_entries[i].folder) ::rmdir(g_entries[i].path);
}

extern "C" void on_signal(int sig) {
    remove_all();
    std::signal(sig, SIG_DFL);
    std::raise(sig);
}

}  // namespace

void install() {
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) std::signal(sig, on_signal);
}

bool add_file(const std::string& path) { return add(path, false); }
bool add_folder(const std::string& path) { return add(path, true); }

void clear() { g_count = 0; }

void remove_registered() {
    remove_all();
    clear();
}

}  // namespace nimbus::interrupt_cleanup
