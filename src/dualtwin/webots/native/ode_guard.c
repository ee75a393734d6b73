/* dualtwin: ODE's world step, made to return when ODE stops on an internal error instead of ending the process.
 *
 * The libode8 package is built with ODE's assertions on (Webots' own ODE is not): a world whose numbers overflow
 * inside the step (a sphere of radius 1e300, an anchor at 1e30 m) makes ODE report "assertion ... failed" and
 * call abort(), which ends every controller and the command with it. Here ODE's debug and error handlers are
 * replaced: inside dualtwin_guarded_step they keep the message and jump back out of the step, which returns -1;
 * anywhere else they print what ODE prints, and ODE then aborts or exits as it always did.
 *
 * Jumping out leaves the interrupted step half done (its working memory is not given back, its bodies are part
 * way through): the caller never steps that world again. The step calls nothing outside ODE (no Python), so the
 * jump crosses only ODE's own frames. The jump target is per thread: simulations in several threads are
 * guarded each in its own.
 *
 * Functions are passed by address (the caller's libode), so this library links to nothing.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stdio.h>

typedef void message_fn(int errnum, const char *msg, va_list ap);
typedef void set_handler_fn(message_fn *handler);
typedef int step_fn(void *world, double stepsize);

static __thread jmp_buf *active = NULL;
static __thread char message[512];

static void report(const char *kind, int errnum, const char *msg, va_list ap) {
    if (active != NULL) {
        int n = snprintf(message, sizeof message, "%s %d: ", kind, errnum);
        if (n < 0 || n >= (int)sizeof message)
            n = 0;
        vsnprintf(message + n, sizeof message - (size_t)n, msg, ap);
        longjmp(*active, 1);
    }
    /* what ODE's own printMessage writes; ODE aborts (debug) or exits (error) when this returns */
    fprintf(stderr, "\n%s %d: ", kind, errnum);
    vfprintf(stderr, msg, ap);
    fprintf(stderr, "\n");
    fflush(stderr);
}

static void on_debug(int errnum, const char *msg, va_list ap) { report("ODE INTERNAL ERROR", errnum, msg, ap); }

static void on_error(int errnum, const char *msg, va_list ap) { report("ODE Error", errnum, msg, ap); }

void dualtwin_ode_guard_install(set_handler_fn *set_debug_handler, set_handler_fn *set_error_handler) {
    set_debug_handler(on_debug);
    set_error_handler(on_error);
}

/* step(world, stepsize); 0 when it returned, -1 when ODE stopped inside it (its message in out). */
int dualtwin_guarded_step(step_fn *step, void *world, double stepsize, char *out, int size) {
    jmp_buf here;
    jmp_buf *outer = active;
    if (setjmp(here) != 0) {
        active = outer;
        snprintf(out, (size_t)size, "%s", message);
        return -1;
    }
    active = &here;
    step(world, stepsize);
    active = outer;
    return 0;
}
