/*
 * First-order lag with a threshold counter: FMI 2.0 model-exchange FMU (ctmm,
 * controllers/fmu/lag_filter_me).
 *
 *     der(x) = frozen ? 0 : (u - x) / time_constant,        y = x
 *     state event  x = threshold  (either direction): crossings += 1, crossing_time = time
 *     time event   time = reset_time:         x := 0
 *
 * Event indicator z = x - threshold.  Only model exchange is provided; the co-simulation entry
 * points report fmi2Error.  Plain C99 against the FMI 2.0 headers shipped with fmpy.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define MODEL_GUID "{3f1c9a7e-0d4b-4b8e-a2c5-6e9d8f7a1b20}"

enum { VR_TIME_CONSTANT, VR_THRESHOLD, VR_RESET_TIME, VR_U, VR_X, VR_DER_X, VR_Y, VR_CROSSING_TIME, N_REALS };
enum { VR_CROSSINGS, N_INTEGERS };
enum { VR_FROZEN, N_BOOLEANS };

typedef enum { MODE_INSTANTIATED, MODE_INITIALIZATION, MODE_EVENT, MODE_CONTINUOUS, MODE_TERMINATED } Mode;

typedef struct {
    fmi2Real r[N_REALS];
    fmi2Integer crossings;
    fmi2Real time;
    int above;     /* side of the threshold at the last event (1: x > threshold) */
    int reset_done;
    fmi2Boolean frozen; /* discrete input: may change only in event mode */
    Mode mode;
    fmi2CallbackFunctions cb;
    char name[64];
} Instance;

static void log_error(Instance *inst, const char *format, ...) {
    char buffer[512];
    va_list args;
    if (inst == NULL || inst->cb.logger == NULL) return;
    va_start(args, format);
    vsnprintf(buffer, sizeof(buffer), format, args);
    va_end(args);
    inst->cb.logger(inst->cb.componentEnvironment, inst->name, fmi2Error, "logStatusError", "%s", buffer);
}

static fmi2Status not_supported(fmi2Component c, const char *function) {
    log_error((Instance *)c, "%s is not supported by this FMU", function);
    return fmi2Error;
}

/* the logger of the shared stubs of unsupported calls (unsupported_fmi2.c, a link to
   controllers/fmu_common/unsupported_fmi2.c, compiled beside this file; its co-simulation stubs are
   exported too, unused by a model-exchange importer) */
fmi2Status ctmm_fmi2_not_supported(fmi2Component c, const char *function);
fmi2Status ctmm_fmi2_not_supported(fmi2Component c, const char *function) { return not_supported(c, function); }

static void compute(Instance *inst) {
    fmi2Real *r = inst->r;
    r[VR_DER_X] = inst->frozen ? 0.0 : (r[VR_U] - r[VR_X]) / r[VR_TIME_CONSTANT];
    r[VR_Y] = r[VR_X];
}

/* ---------------------------------------------------------------- life cycle */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    (void)loggingOn;
    (void)nCategories;
    (void)categories;
    return c == NULL ? fmi2Error : fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Instance tmp, *inst;
    (void)fmuResourceLocation;
    (void)visible;
    (void)loggingOn;
    memset(&tmp, 0, sizeof(tmp));
    if (functions != NULL) tmp.cb = *functions;
    snprintf(tmp.name, sizeof(tmp.name), "%s", instanceName != NULL ? instanceName : "lag_filter_me");
    if (fmuType != fmi2ModelExchange) {
        log_error(&tmp, "lag_filter_me supports model exchange only");
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, MODEL_GUID) != 0) {
        log_error(&tmp, "wrong GUID %s, expected %s", fmuGUID != NULL ? fmuGUID : "(null)", MODEL_GUID);
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof(Instance));
    if (inst == NULL) return NULL;
    *inst = tmp;
    inst->r[VR_TIME_CONSTANT] = 0.5;
    inst->r[VR_THRESHOLD] = 0.5;
    inst->r[VR_RESET_TIME] = 1e300;
    inst->r[VR_CROSSING_TIME] = -1.0;
    inst->mode = MODE_INSTANTIATED;
    return (fmi2Component)inst;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (c == NULL) return fmi2Error;
    ((Instance *)c)->time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst == NULL) return fmi2Error;
    if (!(inst->r[VR_TIME_CONSTANT] > 0.0)) {
        log_error(inst, "time_constant must be > 0, got %g", inst->r[VR_TIME_CONSTANT]);
        return fmi2Error;
    }
    inst->mode = MODE_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst == NULL || inst->mode != MODE_INITIALIZATION) return fmi2Error;
    inst->above = inst->r[VR_X] > inst->r[VR_THRESHOLD];
    compute(inst);
    inst->mode = MODE_EVENT;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    ((Instance *)c)->mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) { return not_supported(c, "fmi2Reset"); }

/* ---------------------------------------------------------------- values */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    if (inst == NULL) return fmi2Error;
    compute(inst);
    for (k = 0; k < nvr; k++) {
        if (vr[k] >= N_REALS) {
            log_error(inst, "fmi2GetReal: unknown value reference %u", (unsigned)vr[k]);
            return fmi2Error;
        }
        value[k] = inst->r[vr[k]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    if (inst == NULL) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        if (vr[k] > VR_X) {
            log_error(inst, "fmi2SetReal: value reference %u cannot be set", (unsigned)vr[k]);
            return fmi2Error;
        }
        if (vr[k] < VR_U && inst->mode != MODE_INSTANTIATED && inst->mode != MODE_INITIALIZATION) {
            log_error(inst, "fmi2SetReal: parameters are fixed after initialization");
            return fmi2Error;
        }
        inst->r[vr[k]] = value[k];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    if (inst == NULL) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_CROSSINGS) return not_supported(c, "fmi2GetInteger of this value reference");
        value[k] = inst->crossings;
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    (void)vr;
    (void)value;
    return nvr == 0 ? fmi2OK : not_supported(c, "fmi2SetInteger");
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    if (inst == NULL) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_FROZEN) return not_supported(c, "fmi2GetBoolean of this value reference");
        value[k] = inst->frozen;
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    Instance *inst = (Instance *)c;
    size_t k;
    if (inst == NULL) return fmi2Error;
    if (nvr > 0 && inst->mode == MODE_CONTINUOUS) {
        log_error(inst, "fmi2SetBoolean: the discrete input 'frozen' can be set only in event mode");
        return fmi2Error;
    }
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_FROZEN) return not_supported(c, "fmi2SetBoolean of this value reference");
        inst->frozen = value[k];
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    (void)vr;
    (void)value;
    return nvr == 0 ? fmi2OK : not_supported(c, "fmi2GetString");
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    (void)vr;
    (void)value;
    return nvr == 0 ? fmi2OK : not_supported(c, "fmi2SetString");
}

/* ---------------------------------------------------------------- model exchange */

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    ((Instance *)c)->mode = MODE_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    Instance *inst = (Instance *)c;
    int above;
    if (inst == NULL || info == NULL || inst->mode != MODE_EVENT) return fmi2Error;
    memset(info, 0, sizeof(*info));
    if (!inst->reset_done && inst->time >= inst->r[VR_RESET_TIME]) {
        inst->r[VR_X] = 0.0;
        inst->reset_done = 1;
        info->valuesOfContinuousStatesChanged = fmi2True;
    }
    above = inst->r[VR_X] > inst->r[VR_THRESHOLD];
    if (above != inst->above && !info->valuesOfContinuousStatesChanged) { /* a crossing, not a jump */
        inst->crossings += 1;
        inst->r[VR_CROSSING_TIME] = inst->time;
    }
    inst->above = above;
    if (!inst->reset_done && inst->r[VR_RESET_TIME] < 1e299) {
        info->nextEventTimeDefined = fmi2True;
        info->nextEventTime = inst->r[VR_RESET_TIME];
    }
    compute(inst);
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    ((Instance *)c)->mode = MODE_CONTINUOUS;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c == NULL) return fmi2Error;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    if (c == NULL) return fmi2Error;
    ((Instance *)c)->time = time;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    if (c == NULL || nx != 1) return fmi2Error;
    ((Instance *)c)->r[VR_X] = x[0];
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    Instance *inst = (Instance *)c;
    if (inst == NULL || nx != 1) return fmi2Error;
    compute(inst);
    derivatives[0] = inst->r[VR_DER_X];
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    Instance *inst = (Instance *)c;
    if (inst == NULL || ni != 1) return fmi2Error;
    eventIndicators[0] = inst->r[VR_X] - inst->r[VR_THRESHOLD];
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    if (c == NULL || nx != 1) return fmi2Error;
    x[0] = ((Instance *)c)->r[VR_X];
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    if (c == NULL || nx != 1) return fmi2Error;
    x_nominal[0] = 1.0;
    return fmi2OK;
}

/* ---------------------------------------------------------------- not provided */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) {
    (void)s;
    return not_supported(c, "fmi2GetFMUstate");
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) {
    (void)s;
    return not_supported(c, "fmi2SetFMUstate");
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) {
    (void)s;
    return not_supported(c, "fmi2FreeFMUstate");
}
