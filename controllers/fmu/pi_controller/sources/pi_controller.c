/*
 * PI controller with an internal integrator: FMI 2.0 co-simulation FMU
 * (ctmm, controllers/fmu/pi_controller).
 *
 *     e = reference - y
 *     u = kp * e + ki * integral          computed whenever u is read (direct feedthrough via kp)
 *     integral <- integral + h * e        in fmi2DoStep(t, h): forward Euler, exact for e held on [t, t+h)
 *
 * With kd = 0 and limit = None this is the law of ctmm.controllers.pid.PID.  The integrator is the
 * FMU's internal state, saved and restored by fmi2GetFMUstate / fmi2SetFMUstate.
 *
 * Testing aids: fmi2DoStep returns fmi2Error if the input is not finite or if the
 * communication point has reached the parameter "fail_at_time" [s].
 *
 * Plain C99 against the FMI 2.0 headers shipped with fmpy (fmpy/c-code).  Build with
 * ctmm.control.fmu.build_fmu("controllers/fmu/pi_controller").
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define MODEL_GUID "{9f6b9897-26f2-4244-a91f-4edd80cb5d8a}"

/* value references (must match modelDescription.xml) */
enum { VR_KP, VR_KI, VR_REFERENCE, VR_FAIL_AT_TIME, VR_Y, VR_U, VR_INTEGRAL, N_REALS };

typedef enum { MODE_INSTANTIATED, MODE_INITIALIZATION, MODE_STEP, MODE_TERMINATED, MODE_ERROR } Mode;

/* Everything fmi2GetFMUstate has to copy. */
typedef struct {
    fmi2Real r[N_REALS];
    fmi2Real time;
    Mode mode;
} Data;

typedef struct {
    Data data;
    char *instanceName;
    fmi2CallbackFunctions cb;
    fmi2Boolean loggingOn;
} Instance;

static void set_start_values(Data *d) {
    memset(d, 0, sizeof(*d));
    d->r[VR_KP] = 1.0;
    d->r[VR_KI] = 0.0;
    d->r[VR_REFERENCE] = 0.0;
    d->r[VR_FAIL_AT_TIME] = 1e300;
    d->r[VR_Y] = 0.0;
    d->r[VR_U] = 0.0;
    d->r[VR_INTEGRAL] = 0.0;
    d->time = 0.0;
    d->mode = MODE_INSTANTIATED;
}

static void *allocate(Instance *inst, size_t size) {
    if (inst != NULL && inst->cb.allocateMemory != NULL) return inst->cb.allocateMemory(1, size);
    return calloc(1, size);
}

static void release(Instance *inst, void *ptr) {
    if (ptr == NULL) return;
    if (inst != NULL && inst->cb.freeMemory != NULL) inst->cb.freeMemory(ptr);
    else free(ptr);
}

/* Errors are always reported; other messages only with logging switched on. */
static void log_message(Instance *inst, fmi2Status status, const char *category, const char *format, ...) {
    char buffer[512];
    va_list args;
    if (inst == NULL || inst->cb.logger == NULL) return;
    if (status < fmi2Error && !inst->loggingOn) return;
    va_start(args, format);
    vsnprintf(buffer, sizeof(buffer), format, args);
    va_end(args);
    inst->cb.logger(inst->cb.componentEnvironment, inst->instanceName, status, category, "%s", buffer);
}

static fmi2Status not_supported(fmi2Component c, const char *function) {
    log_message((Instance *)c, fmi2Error, "logStatusError", "%s is not supported by this FMU", function);
    return fmi2Error;
}

/* the logger of the shared stubs of unsupported calls (unsupported_fmi2.c, a link to
   controllers/fmu_common/unsupported_fmi2.c, compiled beside this file) */
fmi2Status ctmm_fmi2_not_supported(fmi2Component c, const char *function);
fmi2Status ctmm_fmi2_not_supported(fmi2Component c, const char *function) { return not_supported(c, function); }

/* The output equation. */
static void compute_output(Data *d) {
    d->r[VR_U] = d->r[VR_KP] * (d->r[VR_REFERENCE] - d->r[VR_Y]) + d->r[VR_KI] * d->r[VR_INTEGRAL];
}

/* ---------------------------------------------------------------- common functions */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    (void)nCategories;
    (void)categories;
    if (c == NULL) return fmi2Error;
    ((Instance *)c)->loggingOn = loggingOn;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Instance tmp;
    Instance *inst;
    size_t length;
    (void)fmuResourceLocation;
    (void)visible;
    memset(&tmp, 0, sizeof(tmp));
    if (functions != NULL) tmp.cb = *functions;
    tmp.instanceName = (char *)(instanceName != NULL ? instanceName : "pi_controller");
    tmp.loggingOn = loggingOn;
    if (fmuType != fmi2CoSimulation) {
        log_message(&tmp, fmi2Error, "logStatusError", "pi_controller supports co-simulation only");
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, MODEL_GUID) != 0) {
        log_message(&tmp, fmi2Error, "logStatusError", "wrong GUID %s, expected %s",
                    fmuGUID != NULL ? fmuGUID : "(null)", MODEL_GUID);
        return NULL;
    }
    inst = (Instance *)allocate(&tmp, sizeof(Instance));
    if (inst == NULL) return NULL;
    *inst = tmp;
    length = strlen(tmp.instanceName) + 1;
    inst->instanceName = (char *)allocate(&tmp, length);
    if (inst->instanceName == NULL) {
        release(&tmp, inst);
        return NULL;
    }
    memcpy(inst->instanceName, tmp.instanceName, length);
    set_start_values(&inst->data);
    return (fmi2Component)inst;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = (Instance *)c;
    fmi2CallbackFunctions cb;
    if (inst == NULL) return;
    cb = inst->cb;
    if (cb.freeMemory != NULL) {
        cb.freeMemory(inst->instanceName);
        cb.freeMemory(inst);
    } else {
        free(inst->instanceName);
        free(inst);
    }
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *inst = (Instance *)c;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (inst == NULL) return fmi2Error;
    if (inst->data.mode != MODE_INSTANTIATED) {
        log_message(inst, fmi2Error, "logStatusError", "fmi2SetupExperiment called after initialization");
        return fmi2Error;
    }
    inst->data.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst == NULL) return fmi2Error;
    if (inst->data.mode != MODE_INSTANTIATED) {
        log_message(inst, fmi2Error, "logStatusError", "fmi2EnterInitializationMode called twice");
        return fmi2Error;
    }
    inst->data.mode = MODE_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst == NULL) return fmi2Error;
    if (inst->data.mode != MODE_INITIALIZATION) {
        log_message(inst, fmi2Error, "logStatusError", "fmi2ExitInitializationMode outside initialization");
        return fmi2Error;
    }
    compute_output(&inst->data);
    inst->data.mode = MODE_STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst == NULL) return fmi2Error;
    inst->data.mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst == NULL) return fmi2Error;
    set_start_values(&inst->data);
    return fmi2OK;
}

/* ---------------------------------------------------------------- getting and setting values */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    if (inst == NULL) return fmi2Error;
    if (nvr > 0 && (vr == NULL || value == NULL)) return fmi2Error;
    compute_output(&inst->data);
    for (k = 0; k < nvr; k++) {
        if (vr[k] >= N_REALS) {
            log_message(inst, fmi2Error, "logStatusError", "fmi2GetReal: unknown value reference %u",
                        (unsigned)vr[k]);
            return fmi2Error;
        }
        value[k] = inst->data.r[vr[k]];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    (void)vr;
    (void)value;
    if (nvr == 0) return fmi2OK;
    return not_supported(c, "fmi2GetInteger (the FMU has no Integer variables)");
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    if (nvr == 0) return fmi2OK;
    return not_supported(c, "fmi2GetBoolean (the FMU has no Boolean variables)");
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    (void)vr;
    (void)value;
    if (nvr == 0) return fmi2OK;
    return not_supported(c, "fmi2GetString (the FMU has no String variables)");
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    if (inst == NULL) return fmi2Error;
    if (nvr > 0 && (vr == NULL || value == NULL)) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        if (vr[k] >= VR_U) {
            log_message(inst, fmi2Error, "logStatusError",
                        "fmi2SetReal: value reference %u is not a parameter or input", (unsigned)vr[k]);
            return fmi2Error;
        }
    }
    for (k = 0; k < nvr; k++) inst->data.r[vr[k]] = value[k];
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    (void)vr;
    (void)value;
    if (nvr == 0) return fmi2OK;
    return not_supported(c, "fmi2SetInteger (the FMU has no Integer variables)");
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    if (nvr == 0) return fmi2OK;
    return not_supported(c, "fmi2SetBoolean (the FMU has no Boolean variables)");
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    (void)vr;
    (void)value;
    if (nvr == 0) return fmi2OK;
    return not_supported(c, "fmi2SetString (the FMU has no String variables)");
}

/* ---------------------------------------------------------------- FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    Data *copy;
    if (inst == NULL || FMUstate == NULL) return fmi2Error;
    copy = (Data *)*FMUstate;
    if (copy == NULL) {
        copy = (Data *)allocate(inst, sizeof(Data));
        if (copy == NULL) {
            log_message(inst, fmi2Error, "logStatusError", "fmi2GetFMUstate: out of memory");
            return fmi2Error;
        }
    }
    *copy = inst->data;
    *FMUstate = (fmi2FMUstate)copy;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    Instance *inst = (Instance *)c;
    if (inst == NULL || FMUstate == NULL) return fmi2Error;
    inst->data = *(const Data *)FMUstate;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    if (inst == NULL || FMUstate == NULL) return fmi2Error;
    release(inst, *FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

/* ---------------------------------------------------------------- co-simulation */

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *inst = (Instance *)c;
    Data *d;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (inst == NULL) return fmi2Error;
    d = &inst->data;
    if (d->mode != MODE_STEP) {
        log_message(inst, fmi2Error, "logStatusError", "fmi2DoStep called outside step mode");
        return fmi2Error;
    }
    if (!(communicationStepSize > 0.0)) {
        log_message(inst, fmi2Error, "logStatusError", "fmi2DoStep: step size %g is not > 0",
                    communicationStepSize);
        return fmi2Error;
    }
    if (!isfinite(d->r[VR_Y])) {
        log_message(inst, fmi2Error, "logStatusError", "fmi2DoStep at t = %.17g: input not finite (y = %g)",
                    currentCommunicationPoint, d->r[VR_Y]);
        d->mode = MODE_ERROR;
        return fmi2Error;
    }
    if (currentCommunicationPoint >= d->r[VR_FAIL_AT_TIME]) {
        log_message(inst, fmi2Error, "logStatusError", "fmi2DoStep at t = %.17g: reached fail_at_time = %.17g",
                    currentCommunicationPoint, d->r[VR_FAIL_AT_TIME]);
        d->mode = MODE_ERROR;
        return fmi2Error;
    }
    d->r[VR_INTEGRAL] += communicationStepSize * (d->r[VR_REFERENCE] - d->r[VR_Y]);
    compute_output(d);
    d->time = currentCommunicationPoint + communicationStepSize;
    return fmi2OK;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    Instance *inst = (Instance *)c;
    if (inst == NULL || value == NULL) return fmi2Error;
    if (s == fmi2LastSuccessfulTime) {
        *value = inst->data.time;
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    Instance *inst = (Instance *)c;
    if (inst == NULL || value == NULL) return fmi2Error;
    if (s == fmi2Terminated) {
        *value = fmi2False;
        return fmi2OK;
    }
    return fmi2Discard;
}
