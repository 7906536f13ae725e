// A full disk without root: while a FileSizeLimit lives, files this process writes cannot grow
// beyond `bytes` (RLIMIT_FSIZE). write() and fallocate() then fail with EFBIG ("File too
// large") where a full disk gives ENOSPC, through the same code paths. SIGXFSZ, which would
// kill the process, is ignored meanwhile. Not collective: set it on every rank that writes.
#pragma once

#include <sys/resource.h>

#include <csignal>

namespace nimbus::test {

class FileSizeLimit {
public:
    explicit FileSizeLimit(rlim_t bytes) {
        old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
        getrlimit(RLIMIT_FSIZE, &old_);
        rlimit lim = old_;
        lim.rlim_cur = bytes;
        setrlimit(RLIMIT_FSIZE, &lim);
    }
    ~FileSizeLimit() {
        setrlimit(RLIMIT_FSIZE, &old_);
        std::signal(SIGXFSZ, old_handler_);
    }
    FileSizeLimit(const FileSizeLimit&) = delete;
    FileSizeLimit& operator=(const FileSizeLimit&) = delete;

private:
    rlimit old_{};
    void (*old_handler_)(int) = nullptr;
};

}  // namespace nimbus::test
