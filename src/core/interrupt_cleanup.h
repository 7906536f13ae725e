// What a run removes when a signal ends it (Ctrl-C, mpiexec passing on SIGTERM, a batch
// system's time limit): the temporaries of its output files and the folders it created, so an
// interrupted run leaves the output folder as it found it, like a failed one does. A failed run
// cleans up by unwinding (OutputFiles, the pipeline's created folders); a signal does not
// unwind, so those register their paths here as well.
//
//   interrupt_cleanup::install(rank == 0);        // once, before the run (SIGINT, SIGTERM, SIGHUP);
//                                                 // rank 0 says on stderr what was cleaned up
//   interrupt_cleanup::add_file("out/a.h5.123.tmp");
//   interrupt_cleanup::add_folder("out");         // removed only if empty, after the files
//   interrupt_cleanup::committed();               // the outputs are in place: nothing to remove,
//                                                 // and a signal says they are complete
//   interrupt_cleanup::clear();                   // a fresh start: nothing to remove, nothing written
//
// The handler only calls unlink(2), rmdir(2), write(2), strlen(3), sigaction(2) and raise(3),
// which are async-signal-safe; then
// the signal takes its default action (the exit status says so). A signal the process was
// started with ignored (nohup) stays ignored.
// Paths are kept in a fixed table (kMaxPaths of kMaxPathBytes); beyond it they are not
// registered (add_* returns false) and a signal leaves them behind. Not thread-safe: call from
// the thread that runs the pipeline.
#pragma once

#include <string>

namespace nimbus::interrupt_cleanup {

inline constexpr int kMaxPaths = 64;
inline constexpr int kMaxPathBytes = 4096;

void install(bool speaks);
bool add_file(const std::string& path);
bool add_folder(const std::string& path);
void clear();
void committed();

// While one exists, a handled signal is only noted, and acted on (cleanup, then the default
// action) when it is destroyed: for the renames that replace a previous run's files, which must
// not be cut between moving the old files aside and putting the new ones in place.
class Deferred {
public:
    Deferred();
    ~Deferred();
    Deferred(const Deferred&) = delete;
    Deferred& operator=(const Deferred&) = delete;
};

}  // namespace nimbus::interrupt_cleanup
