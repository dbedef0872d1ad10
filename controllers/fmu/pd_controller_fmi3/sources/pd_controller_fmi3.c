/*
 * Saturated PD controller: FMI 3.0 co-simulation FMU (ctmm, controllers/fmu/pd_controller_fmi3).
 *
 *     u = clip(kp * (reference - y) - kd * ydot, -limit, limit)      (no clipping when limit <= 0)
 *
 * Same law as the FMI 2.0 source controllers/fmu/pd_controller: the output is computed from the
 * current inputs whenever it is read (direct feedthrough), fmi3DoStep advances the time.  Testing
 * aids: fmi3DoStep returns fmi3Error if an input is not finite or if the communication point has
 * reached the parameter "fail_at_time" [s].
 *
 * Only co-simulation is provided; the model-exchange and scheduled-execution entry points (which
 * the FMI 3 standard still requires to be exported) report fmi3Error.
 *
 * Plain C99 against the FMI 3.0 headers shipped with fmpy (fmpy/c-code).
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#define INSTANTIATION_TOKEN "{ce437997-3449-4f44-8132-d86f52236c7d}"

/* value references (must match modelDescription.xml); 0 is the independent variable "time" */
enum { VR_TIME, VR_KP, VR_KD, VR_LIMIT, VR_REFERENCE, VR_FAIL_AT_TIME, VR_Y, VR_YDOT, VR_U, N_FLOATS };

typedef enum { MODE_INSTANTIATED, MODE_INITIALIZATION, MODE_STEP, MODE_TERMINATED, MODE_ERROR } Mode;

/* Everything fmi3GetFMUState has to copy (r[VR_TIME] is the time). */
typedef struct {
    fmi3Float64 r[N_FLOATS];
    Mode mode;
} Data;

typedef struct {
    Data data;
    char *instanceName;
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback logMessage;
    fmi3Boolean loggingOn;
} Instance;

static void set_start_values(Data *d) {
    memset(d, 0, sizeof(*d));
    d->r[VR_TIME] = 0.0;
    d->r[VR_KP] = 1.0;
    d->r[VR_KD] = 0.0;
    d->r[VR_LIMIT] = 0.0;
    d->r[VR_REFERENCE] = 0.0;
    d->r[VR_FAIL_AT_TIME] = 1e300;
    d->r[VR_Y] = 0.0;
    d->r[VR_YDOT] = 0.0;
    d->r[VR_U] = 0.0;
    d->mode = MODE_INSTANTIATED;
}

/* Errors are always reported; other messages only with logging switched on. */
static void log_message(Instance *inst, fmi3Status status, const char *category, const char *format, ...) {
    char buffer[512];
    va_list args;
    if (inst == NULL || inst->logMessage == NULL) return;
    if (status < fmi3Error && !inst->loggingOn) return;
    va_start(args, format);
    vsnprintf(buffer, sizeof(buffer), format, args);
    va_end(args);
    inst->logMessage(inst->environment, status, category, buffer);
}

static fmi3Status unsupported(fmi3Instance instance, const char *function) {
    log_message((Instance *)instance, fmi3Error, "logStatusError", "%s is not supported by this FMU", function);
    return fmi3Error;
}

/* the logger of the shared stubs of unsupported calls (unsupported_fmi3.c, a link to
   controllers/fmu_common/unsupported_fmi3.c, compiled beside this file) */
fmi3Status ctmm_fmi3_not_supported(fmi3Instance instance, const char *function);
fmi3Status ctmm_fmi3_not_supported(fmi3Instance instance, const char *function) { return unsupported(instance, function); }

static void compute_output(Data *d) {
    const fmi3Float64 *r = d->r;
    fmi3Float64 u = r[VR_KP] * (r[VR_REFERENCE] - r[VR_Y]) - r[VR_KD] * r[VR_YDOT];
    if (r[VR_LIMIT] > 0.0) {
        if (u > r[VR_LIMIT]) u = r[VR_LIMIT];
        else if (u < -r[VR_LIMIT]) u = -r[VR_LIMIT];
    }
    d->r[VR_U] = u;
}

/* ---------------------------------------------------------------- implemented functions */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    (void)nCategories;
    (void)categories;
    if (instance == NULL) return fmi3Error;
    ((Instance *)instance)->loggingOn = loggingOn;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    Instance tmp;
    Instance *inst;
    const char *name = instanceName != NULL ? instanceName : "pd_controller_fmi3";
    (void)resourcePath;
    (void)visible;
    (void)eventModeUsed;
    (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    memset(&tmp, 0, sizeof(tmp));
    tmp.instanceName = (char *)name;
    tmp.environment = instanceEnvironment;
    tmp.logMessage = logMessage;
    tmp.loggingOn = loggingOn;
    if (instantiationToken == NULL || strcmp(instantiationToken, INSTANTIATION_TOKEN) != 0) {
        log_message(&tmp, fmi3Error, "logStatusError", "wrong instantiation token %s, expected %s",
                    instantiationToken != NULL ? instantiationToken : "(null)", INSTANTIATION_TOKEN);
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof(Instance));
    if (inst == NULL) return NULL;
    *inst = tmp;
    inst->instanceName = (char *)malloc(strlen(name) + 1);
    if (inst->instanceName == NULL) {
        free(inst);
        return NULL;
    }
    strcpy(inst->instanceName, name);
    set_start_values(&inst->data);
    return (fmi3Instance)inst;
}

void fmi3FreeInstance(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    if (inst == NULL) return;
    free(inst->instanceName);
    free(inst);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Instance *inst = (Instance *)instance;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (inst == NULL) return fmi3Error;
    if (inst->data.mode != MODE_INSTANTIATED) {
        log_message(inst, fmi3Error, "logStatusError", "fmi3EnterInitializationMode called twice");
        return fmi3Error;
    }
    inst->data.r[VR_TIME] = startTime;
    inst->data.mode = MODE_INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    if (inst == NULL) return fmi3Error;
    if (inst->data.mode != MODE_INITIALIZATION) {
        log_message(inst, fmi3Error, "logStatusError", "fmi3ExitInitializationMode outside initialization");
        return fmi3Error;
    }
    compute_output(&inst->data);
    inst->data.mode = MODE_STEP; /* no event mode: step mode follows initialization */
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    if (inst == NULL) return fmi3Error;
    inst->data.mode = MODE_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    if (inst == NULL) return fmi3Error;
    set_start_values(&inst->data);
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float64 values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t k;
    if (inst == NULL) return fmi3Error;
    if (nValues != nValueReferences) {
        log_message(inst, fmi3Error, "logStatusError", "fmi3GetFloat64: all variables are scalars");
        return fmi3Error;
    }
    compute_output(&inst->data);
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] >= N_FLOATS) {
            log_message(inst, fmi3Error, "logStatusError", "fmi3GetFloat64: unknown value reference %u",
                        (unsigned)valueReferences[k]);
            return fmi3Error;
        }
        values[k] = inst->data.r[valueReferences[k]];
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float64 values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t k;
    if (inst == NULL) return fmi3Error;
    if (nValues != nValueReferences) {
        log_message(inst, fmi3Error, "logStatusError", "fmi3SetFloat64: all variables are scalars");
        return fmi3Error;
    }
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] == VR_TIME || valueReferences[k] >= VR_U) {
            log_message(inst, fmi3Error, "logStatusError",
                        "fmi3SetFloat64: value reference %u is not a parameter or input", (unsigned)valueReferences[k]);
            return fmi3Error;
        }
    }
    for (k = 0; k < nValueReferences; k++) inst->data.r[valueReferences[k]] = values[k];
    return fmi3OK;
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    Instance *inst = (Instance *)instance;
    Data *copy;
    if (inst == NULL || FMUState == NULL) return fmi3Error;
    copy = (Data *)*FMUState;
    if (copy == NULL) {
        copy = (Data *)calloc(1, sizeof(Data));
        if (copy == NULL) return fmi3Error;
    }
    *copy = inst->data;
    *FMUState = (fmi3FMUState)copy;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    Instance *inst = (Instance *)instance;
    if (inst == NULL || FMUState == NULL) return fmi3Error;
    inst->data = *(const Data *)FMUState;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    if (instance == NULL || FMUState == NULL) return fmi3Error;
    free(*FMUState);
    *FMUState = NULL;
    return fmi3OK;
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    if (inst == NULL) return fmi3Error;
    inst->data.mode = MODE_STEP;
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    Instance *inst = (Instance *)instance;
    Data *d;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (inst == NULL) return fmi3Error;
    d = &inst->data;
    if (eventHandlingNeeded != NULL) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation != NULL) *terminateSimulation = fmi3False;
    if (earlyReturn != NULL) *earlyReturn = fmi3False;
    if (lastSuccessfulTime != NULL) *lastSuccessfulTime = d->r[VR_TIME];
    if (d->mode != MODE_STEP) {
        log_message(inst, fmi3Error, "logStatusError", "fmi3DoStep called outside step mode");
        return fmi3Error;
    }
    if (!(communicationStepSize > 0.0)) {
        log_message(inst, fmi3Error, "logStatusError", "fmi3DoStep: step size %g is not > 0", communicationStepSize);
        return fmi3Error;
    }
    if (!isfinite(d->r[VR_Y]) || !isfinite(d->r[VR_YDOT])) {
        log_message(inst, fmi3Error, "logStatusError", "fmi3DoStep at t = %.17g: input not finite (y = %g, ydot = %g)",
                    currentCommunicationPoint, d->r[VR_Y], d->r[VR_YDOT]);
        d->mode = MODE_ERROR;
        return fmi3Error;
    }
    if (currentCommunicationPoint >= d->r[VR_FAIL_AT_TIME]) {
        log_message(inst, fmi3Error, "logStatusError", "fmi3DoStep at t = %.17g: reached fail_at_time = %.17g",
                    currentCommunicationPoint, d->r[VR_FAIL_AT_TIME]);
        d->mode = MODE_ERROR;
        return fmi3Error;
    }
    compute_output(d);
    d->r[VR_TIME] = currentCommunicationPoint + communicationStepSize;
    if (lastSuccessfulTime != NULL) *lastSuccessfulTime = d->r[VR_TIME];
    return fmi3OK;
}

/* ---------------------------------------------------------------- not provided by this FMU */

#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif

#define GET_SET(name, type, constness)                                                                    \
    fmi3Status name(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, \
                    constness type values[], size_t nValues) {                                             \
        if (nValueReferences == 0) return fmi3OK;                                                          \
        return unsupported(instance, #name " (the FMU has only Float64 variables)");                       \
    }

GET_SET(fmi3GetFloat32, fmi3Float32, )
GET_SET(fmi3GetInt8, fmi3Int8, )
GET_SET(fmi3GetUInt8, fmi3UInt8, )
GET_SET(fmi3GetInt16, fmi3Int16, )
GET_SET(fmi3GetUInt16, fmi3UInt16, )
GET_SET(fmi3GetInt32, fmi3Int32, )
GET_SET(fmi3GetUInt32, fmi3UInt32, )
GET_SET(fmi3GetInt64, fmi3Int64, )
GET_SET(fmi3GetUInt64, fmi3UInt64, )
GET_SET(fmi3GetBoolean, fmi3Boolean, )
GET_SET(fmi3GetString, fmi3String, )
GET_SET(fmi3SetFloat32, fmi3Float32, const)
GET_SET(fmi3SetInt8, fmi3Int8, const)
GET_SET(fmi3SetUInt8, fmi3UInt8, const)
GET_SET(fmi3SetInt16, fmi3Int16, const)
GET_SET(fmi3SetUInt16, fmi3UInt16, const)
GET_SET(fmi3SetInt32, fmi3Int32, const)
GET_SET(fmi3SetUInt32, fmi3UInt32, const)
GET_SET(fmi3SetInt64, fmi3Int64, const)
GET_SET(fmi3SetUInt64, fmi3UInt64, const)
GET_SET(fmi3SetBoolean, fmi3Boolean, const)
GET_SET(fmi3SetString, fmi3String, const)

