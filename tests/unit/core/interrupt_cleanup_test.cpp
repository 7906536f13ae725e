// interrupt_cleanup: a handled signal removes the registered temporaries and (empty) folders and
// ends the process by that signal; inside a Deferred it waits until the Deferred ends. Each case
// runs in a forked child (no MPI there: it only registers, signals itself and dies), so the
// test process keeps its own signal dispositions.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "src/core/interrupt_cleanup.h"

namespace nimbus {
namespace {

namespace fs = std::filesystem;

// A fresh folder holding one file, both to be registered by the child.
struct Scratch {
    fs::path dir, file, kept;
    explicit Scratch(const std::string& name) {
        dir = fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
        fs::remove_all(dir);
        fs::create_directories(dir / "made");
        file = dir / "made" / "out.h5.tmp";
        kept = dir / "previous.h5";  // a file the run did not make: never touched
        std::ofstream(file) << "partial";
        std::ofstream(kept) << "old run";
    }
    ~Scratch() { fs::remove_all(dir); }
};

// Runs `child` in a forked process; returns its wait status.
template <class F>
int in_child(F&& child) {
    const pid_t pid = ::fork();
    if (pid == 0) {
        child();
        ::_exit(0);
    }
    int status = 0;
    ::waitpid(pid, &status, 0);
    return status;
}

TEST(InterruptCleanup, SignalRemovesRegisteredPathsAndEndsByIt) {
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
        Scratch s("nimbus_interrupt");
        const int status = in_child([&] {
            ::signal(sig, SIG_DFL);
            interrupt_cleanup::install(true);
            interrupt_cleanup::add_folder((s.dir / "made").string());
            interrupt_cleanup::add_file(s.file.string());
            ::raise(sig);
            ::_exit(3);  // not reached when the signal ends the process
        });
        ASSERT_TRUE(WIFSIGNALED(status)) << "signal " << sig << ", status " << status;
        EXPECT_EQ(WTERMSIG(status), sig);
        EXPECT_FALSE(fs::exists(s.file)) << sig;
        EXPECT_FALSE(fs::exists(s.dir / "made")) << sig;
        EXPECT_TRUE(fs::exists(s.kept)) << sig;
    }
}

// The same signal twice at once on two threads (timeout(1) signals the command and then its
// process group; MPI's threads may take either): the second must not end the process while the
// first cleans up. With a one-shot handler (SA_RESETHAND) the second signal found the default
// action and killed the child mid-cleanup, leaving files behind.
TEST(InterruptCleanup, SecondSignalOnAnotherThreadWaitsForTheCleanup) {
    for (int round = 0; round < 20; ++round) {
        Scratch s("nimbus_interrupt_twice");
        // Many files, so that the cleanup takes a while.
        std::vector<fs::path> files;
        for (int q = 0; q < interrupt_cleanup::kMaxPaths - 2; ++q) {  // + the folder and s.file
            files.push_back(s.dir / "made" / ("part" + std::to_string(q) + ".tmp"));
            std::ofstream(files.back()) << "partial";
        }
        const int status = in_child([&] {
            ::signal(SIGINT, SIG_DFL);
            interrupt_cleanup::install(true);
            interrupt_cleanup::add_folder((s.dir / "made").string());
            interrupt_cleanup::add_file(s.file.string());
            for (const auto& f : files) interrupt_cleanup::add_file(f.string());
            std::atomic<int> ready{0};
            auto shoot = [&] {
                ready.fetch_add(1);
                while (ready.load() < 2) {}
                ::pthread_kill(::pthread_self(), SIGINT);
            };
            std::thread a(shoot), b(shoot);
            a.join();
            b.join();
            ::_exit(3);  // not reached
        });
        ASSERT_TRUE(WIFSIGNALED(status)) << "round " << round << ", status " << status;
        EXPECT_EQ(WTERMSIG(status), SIGINT);
        for (const auto& f : files) ASSERT_FALSE(fs::exists(f)) << "round " << round << ": " << f;
        EXPECT_FALSE(fs::exists(s.dir / "made")) << "round " << round;
        EXPECT_TRUE(fs::exists(s.kept));
    }
}

TEST(InterruptCleanup, ClearedPathsStay) {
    Scratch s("nimbus_interrupt_clear");
    const int status = in_child([&] {
        ::signal(SIGTERM, SIG_DFL);
        interrupt_cleanup::install(true);
        interrupt_cleanup::add_folder((s.dir / "made").string());
        interrupt_cleanup::add_file(s.file.string());
        interrupt_cleanup::clear();  // committed
        ::raise(SIGTERM);
    });
    ASSERT_TRUE(WIFSIGNALED(status));
    EXPECT_TRUE(fs::exists(s.file));
}

TEST(InterruptCleanup, DeferredHoldsTheSignalUntilItEnds) {
    Scratch s("nimbus_interrupt_deferred");
    const fs::path marker = s.dir / "after_raise";
    const int status = in_child([&] {
        ::signal(SIGTERM, SIG_DFL);
        interrupt_cleanup::install(true);
        interrupt_cleanup::add_file(s.file.string());
        {
            const interrupt_cleanup::Deferred hold;
            ::raise(SIGTERM);
            // Still alive, nothing removed yet: the renames of a commit would run here.
            if (fs::exists(s.file)) std::ofstream(marker) << "held";
        }
        ::_exit(3);  // not reached: the held signal ends the process when the Deferred ends
    });
    ASSERT_TRUE(WIFSIGNALED(status)) << status;
    EXPECT_EQ(WTERMSIG(status), SIGTERM);
    EXPECT_TRUE(fs::exists(marker)) << "the signal was not held";
    EXPECT_FALSE(fs::exists(s.file)) << "the held signal did not clean up";
}

// What rank 0 says on stderr: a signal after committed() (the outputs are in place, the paths
// forgotten) says they are complete, also when it came during the renames (a Deferred that
// ends after committed()); after clear() it says nothing was written; with paths registered,
// that they were removed. A QA finding: a signal after the commit said "interrupted before
// writing any output" while the run's files had replaced the previous ones.
TEST(InterruptCleanup, TheMessageSaysWhetherTheOutputsWereWritten) {
    enum class Step { committed, committed_while_deferred, committed_then_cleared, registered };
    auto said = [](Step step) {
        Scratch s("nimbus_interrupt_message");
        const fs::path err = s.dir / "stderr.txt";
        const int status = in_child([&] {
            ::signal(SIGTERM, SIG_DFL);
            const int fd = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
            ::dup2(fd, STDERR_FILENO);
            interrupt_cleanup::install(true);
            interrupt_cleanup::add_file(s.file.string());
            if (step == Step::committed_while_deferred) {
                const interrupt_cleanup::Deferred hold;
                ::raise(SIGTERM);
                interrupt_cleanup::committed();
            } else if (step != Step::registered) {
                interrupt_cleanup::committed();
                if (step == Step::committed_then_cleared) interrupt_cleanup::clear();
                ::raise(SIGTERM);
            } else {
                ::raise(SIGTERM);
            }
            ::_exit(3);
        });
        EXPECT_TRUE(WIFSIGNALED(status)) << status;
        EXPECT_EQ(fs::exists(s.file), step != Step::registered);
        std::ifstream in(err);
        return std::string(std::istreambuf_iterator<char>(in), {});
    };
    EXPECT_NE(said(Step::committed).find("after this run's outputs were written: they are complete"), std::string::npos);
    EXPECT_NE(said(Step::committed_while_deferred).find("they are complete"), std::string::npos);
    EXPECT_NE(said(Step::committed_then_cleared).find("before writing any output"), std::string::npos);
    EXPECT_NE(said(Step::registered).find("removed this run's temporary files"), std::string::npos);
}

TEST(InterruptCleanup, IgnoredSignalStaysIgnored) {
    Scratch s("nimbus_interrupt_ignored");
    const int status = in_child([&] {
        ::signal(SIGHUP, SIG_IGN);  // nohup
        interrupt_cleanup::install(true);
        interrupt_cleanup::add_file(s.file.string());
        ::raise(SIGHUP);
        ::_exit(7);
    });
    ASSERT_TRUE(WIFEXITED(status)) << status;
    EXPECT_EQ(WEXITSTATUS(status), 7);
    EXPECT_TRUE(fs::exists(s.file));
}

}  // namespace
}  // namespace nimbus
