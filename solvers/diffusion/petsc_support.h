// PETSc start-up, error handling, options strings and owning handles shared by the PETSc users
// (the diffusion cross-check path and DOM's GMRES). Not collective except ensure_initialized,
// which every rank of comm calls.
//
// Errors: PETSc's default handler prints a traceback with its configure line on the first rank
// of the failing object's communicator, and makes every other rank sleep 10 s and exit(0)
// without MPI_Finalize (mpiexec then reports that the rank exited improperly). A PETSc user
// therefore holds a QuietErrors while it calls PETSc: an error returns its code without a
// word, and check() turns the code into a Failure (an Error) carrying PETSc's one-line message,
// which leaves through the normal path. A collective PETSc call that fails on input every rank
// shares (the options, the grid) fails on every rank; callers make their local stages
// collective (run_collective, src/core/error.h).
#pragma once

#include <petscksp.h>
#include <petscsys.h>

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "src/core/error.h"

namespace nimbus::petsc {

// An Error from a PETSc call; petsc_message() is PETSc's own text (e.g. "Unable to find
// requested PC type foo").
class Failure : public Error {
public:
    Failure(const std::string& what, std::string petsc_message)
        : Error(what), petsc_message_(std::move(petsc_message)) {}
    const std::string& petsc_message() const { return petsc_message_; }

private:
    std::string petsc_message_;
};

// PETSc's message for the error just raised (the text given where it was raised, else the
// generic text of ierr), on one line.
inline std::string error_message(PetscErrorCode ierr) {
    const char* text = nullptr;
    char* specific = nullptr;
    PetscErrorMessage(static_cast<int>(ierr), &text, &specific);
    std::string m = specific != nullptr && *specific != '\0' ? specific : text != nullptr ? text : "unknown error";
    for (char& c : m)
        if (c == '\n') c = ' ';
    while (!m.empty() && m.back() == ' ') m.pop_back();
    return m;
}

// Throws a Failure naming `who` (e.g. "dom (gmres)"), the call and PETSc's message when PETSc
// reports an error; std::bad_alloc when PETSc ran out of memory (src/cmd/main.cpp then aborts
// the run: this rank may have failed alone).
inline void check(PetscErrorCode ierr, const char* who, const std::string& what) {
    if (ierr == 0) return;
    if (ierr == PETSC_ERR_MEM) throw std::bad_alloc();
    const std::string message = error_message(ierr);
    throw Failure(fmt::format("{}: {} failed with PETSc error {}: {}", who, what, static_cast<int>(ierr), message),
                  message);
}

// While alive, a PETSc error returns its code and prints nothing (see above). Scopes nest;
// construct one after ensure_initialized.
class QuietErrors {
public:
    QuietErrors() { PetscPushErrorHandler(PetscReturnErrorHandler, nullptr); }
    ~QuietErrors() { PetscPopErrorHandler(); }
    QuietErrors(const QuietErrors&) = delete;
    QuietErrors& operator=(const QuietErrors&) = delete;
};

// PETSc is initialized here only if the program has not done it, collectively over the ranks of
// comm (a solve may run on a sub-communicator, e.g. MPI_COMM_SELF). PETSC_COMM_WORLD becomes a
// duplicate of comm: comm is usually a Decomposition's, freed with it, and PETSc keeps its world
// until the end of the program.
inline void ensure_initialized(MPI_Comm comm) {
    PetscBool done = PETSC_FALSE;
    check(PetscInitialized(&done), "petsc", "PetscInitialized");
    if (done) return;
    MPI_Comm world = MPI_COMM_NULL;
    MPI_Comm_dup(comm, &world);
    PETSC_COMM_WORLD = world;
    // PETSc's signal handler would replace nimbus's (src/core/interrupt_cleanup.h), which removes
    // an interrupted run's temporaries; PETSc allows this option before PetscInitialize.
    check(PetscOptionsSetValue(nullptr, "-no_signal_handler", nullptr), "petsc", "PetscOptionsSetValue");
    check(PetscInitializeNoArguments(), "petsc", "PetscInitialize");
}

// Owning handles: destroyed at scope exit, also when an error unwinds the scope.
struct OptionsHandle {
    PetscOptions o = nullptr;
    ~OptionsHandle() { if (o) PetscOptionsDestroy(&o); }
};
struct MatHandle {
    Mat m = nullptr;
    ~MatHandle() { if (m) MatDestroy(&m); }
};
struct VecHandle {
    Vec v = nullptr;
    ~VecHandle() { if (v) VecDestroy(&v); }
};
struct KSPHandle {
    KSP ksp = nullptr;
    ~KSPHandle() { if (ksp) KSPDestroy(&ksp); }
};

// One option as written: its name with the dash, its value ("" for none).
struct Option {
    std::string name, value;
    std::string text() const { return value.empty() ? name : name + " " + value; }
};

// An options string read as PetscOptionsInsertString reads it: a word is an option name when it
// is a dash (or two) and a letter, and the word after a name is its value unless it is a name
// itself ("-1" is a value); a "double-quoted value" is one word. PETSc drops the other words
// without a word (a first word that is not a name, a second value): they are `stray`.
struct OptionsText {
    std::vector<Option> options;  // in the order given
    std::vector<std::string> stray;
};

inline OptionsText read_options_text(const std::string& s) {
    std::vector<std::string> words;
    for (size_t i = 0; i < s.size();) {
        if (std::isspace(static_cast<unsigned char>(s[i]))) {
            ++i;
            continue;
        }
        size_t end = i;
        if (s[i] == '"') {
            const size_t close = std::min(s.find('"', i + 1), s.size());
            words.push_back(s.substr(i + 1, close - i - 1));
            end = close + 1;
        } else {
            while (end < s.size() && !std::isspace(static_cast<unsigned char>(s[end]))) ++end;
            words.push_back(s.substr(i, end - i));
        }
        i = end;
    }
    const auto is_name = [](const std::string& w) {
        const size_t at = w.size() > 1 && w[0] == '-' && w[1] == '-' ? 2 : 1;
        return w.size() > at && w[0] == '-' && std::isalpha(static_cast<unsigned char>(w[at]));
    };
    OptionsText out;
    for (size_t i = 0; i < words.size(); ++i) {
        if (!is_name(words[i])) {
            out.stray.push_back(words[i]);
        } else if (i + 1 < words.size() && !is_name(words[i + 1])) {
            out.options.push_back({words[i], words[i + 1]});
            ++i;
        } else {
            out.options.push_back({words[i], ""});
        }
    }
    return out;
}

// The options of `options` that no PETSc object has read (all of them in a database nothing
// has read yet), names with their dash, in PETSc's order.
inline std::vector<Option> unread_options(PetscOptions options) {
    PetscInt n = 0;
    char** names = nullptr;
    char** values = nullptr;
    check(PetscOptionsLeftGet(options, &n, &names, &values), "petsc", "PetscOptionsLeftGet");
    std::vector<Option> out;
    for (PetscInt i = 0; i < n; ++i) out.push_back({std::string("-") + names[i], values[i] ? values[i] : ""});
    PetscOptionsLeftRestore(options, &n, &names, &values);
    return out;
}

}  // namespace nimbus::petsc
