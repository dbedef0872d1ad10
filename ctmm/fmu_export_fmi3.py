"""The FMI 3.0 co-simulation functions of an exported plant FMU (C text; :mod:`ctmm.fmu_export_runtime`).

:data:`FMI3_INTERFACE` wraps the shared core of :data:`ctmm.fmu_export_runtime.CORE` (instance data,
value references, initialisation, the communication step) in the FMI 3.0 functions: Float64 variables
(the inputs, outputs, parameters and start values, and the independent variable ``time``), FMU state
get/set, ``fmi3DoStep`` without event mode, intermediate update or early return.  Every other function
the standard requires is exported and returns ``fmi3Error`` (or ``fmi3OK`` for an empty call), and
model-exchange or scheduled-execution instantiation returns ``NULL``; the calls no ctmm FMU supports are
the stubs shared with the shipped controller FMUs (``controllers/fmu_common/unsupported_fmi3.c``, copied
beside this source by :func:`ctmm.fmu_export_files.write_sources`), logging through
``ctmm_fmi3_not_supported``.
"""
from __future__ import annotations

__all__ = ["FMI3_INTERFACE"]

FMI3_INTERFACE = r"""
/* ================================================================ FMI 3.0 co-simulation */

typedef struct {
    Core *core;
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback logMessage;
    fmi3Boolean loggingOn;
} Instance;

static void interface_log(void *owner, int error, const char *text) {
    Instance *inst = (Instance *)owner;
    if (inst == NULL || inst->logMessage == NULL || (!error && !inst->loggingOn)) return;
    inst->logMessage(inst->environment, error ? fmi3Error : fmi3OK, error ? "logStatusError" : "logAll", text);
}

static fmi3Status not_supported(fmi3Instance instance, const char *function) {
    report(instance, 1, "%s is not supported by this FMU", function);
    return fmi3Error;
}

/* the logger of the shared stubs of unsupported calls (unsupported_fmi3.c, compiled beside this file) */
fmi3Status ctmm_fmi3_not_supported(fmi3Instance instance, const char *function);
fmi3Status ctmm_fmi3_not_supported(fmi3Instance instance, const char *function) { return not_supported(instance, function); }

#define CORE_OF(c) (((Instance *)(c))->core)
#define STATUS(failed) ((failed) ? fmi3Error : fmi3OK)

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
    Instance tmp, *inst;
    (void)instanceName;
    (void)resourcePath;
    (void)visible;
    (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables;
    (void)intermediateUpdate;
    memset(&tmp, 0, sizeof(tmp));
    tmp.environment = instanceEnvironment;
    tmp.logMessage = logMessage;
    tmp.loggingOn = loggingOn;
    if (eventModeUsed || nRequiredIntermediateVariables > 0) {
        report(&tmp, 1, "%s has no event mode and no intermediate variables", MODEL_IDENTIFIER);
        return NULL;
    }
    if (instantiationToken == NULL || strcmp(instantiationToken, MODEL_TOKEN) != 0) {
        report(&tmp, 1, "wrong instantiationToken %s, expected %s",
               instantiationToken != NULL ? instantiationToken : "(null)", MODEL_TOKEN);
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof(Instance));
    if (inst != NULL) {
        *inst = tmp;
        inst->core = core_new();
    }
    if (inst == NULL || inst->core == NULL) {
        report(&tmp, 1, "fmi3InstantiateCoSimulation: out of memory");
        free(inst);
        return NULL;
    }
    return (fmi3Instance)inst;
}

void fmi3FreeInstance(fmi3Instance instance) {
    if (instance == NULL) return;
    core_free(CORE_OF(instance));
    free(instance);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (instance == NULL) return fmi3Error;
    if (CORE_OF(instance)->data.mode != MODE_INSTANTIATED || !isfinite(startTime)) {
        report(instance, 1, "fmi3EnterInitializationMode: called twice or startTime %g not finite", startTime);
        return fmi3Error;
    }
    CORE_OF(instance)->data.start_time = startTime;
    CORE_OF(instance)->data.time = startTime;
    CORE_OF(instance)->data.mode = MODE_INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    return STATUS(core_exit_initialization(CORE_OF(instance), instance));
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    return CORE_OF(instance)->data.mode == MODE_STEP ? fmi3OK : not_supported(instance, "fmi3EnterStepMode here");
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    CORE_OF(instance)->data.mode = MODE_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    core_reset(CORE_OF(instance));
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    if (instance == NULL || nValues != nValueReferences) return fmi3Error;
    return STATUS(core_get(CORE_OF(instance), instance, valueReferences, nValueReferences, values));
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    if (instance == NULL || nValues != nValueReferences) return fmi3Error;
    return STATUS(core_set(CORE_OF(instance), instance, valueReferences, nValueReferences, values));
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    int failed;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (instance == NULL) return fmi3Error;
    failed = core_do_step(CORE_OF(instance), instance, currentCommunicationPoint, communicationStepSize);
    if (eventHandlingNeeded != NULL) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation != NULL) *terminateSimulation = fmi3False;
    if (earlyReturn != NULL) *earlyReturn = fmi3False;
    if (lastSuccessfulTime != NULL) *lastSuccessfulTime = CORE_OF(instance)->data.time;
    return STATUS(failed);
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    Data *copy;
    if (instance == NULL || FMUState == NULL) return fmi3Error;
    copy = core_save(CORE_OF(instance), (Data *)*FMUState);
    if (copy == NULL) return not_supported(instance, "fmi3GetFMUState (out of memory)");
    *FMUState = (fmi3FMUState)copy;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    if (instance == NULL || FMUState == NULL) return fmi3Error;
    CORE_OF(instance)->data = *(const Data *)FMUState;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    if (instance == NULL || FMUState == NULL) return fmi3Error;
    free(*FMUState);
    *FMUState = NULL;
    return fmi3OK;
}

/* variables of other types: none (calls with no value references are fine) */
#define NO_VARIABLES(function, qualifier, type)                                                            \
    fmi3Status function(fmi3Instance instance, const fmi3ValueReference valueReferences[],                 \
                        size_t nValueReferences, qualifier type values[], size_t nValues) {                \
        (void)valueReferences;                                                                              \
        (void)values;                                                                                       \
        (void)nValues;                                                                                      \
        return nValueReferences == 0 ? fmi3OK : not_supported(instance, #function " (Float64 variables only)"); \
    }
NO_VARIABLES(fmi3GetFloat32, , fmi3Float32)
NO_VARIABLES(fmi3GetInt8, , fmi3Int8)
NO_VARIABLES(fmi3GetUInt8, , fmi3UInt8)
NO_VARIABLES(fmi3GetInt16, , fmi3Int16)
NO_VARIABLES(fmi3GetUInt16, , fmi3UInt16)
NO_VARIABLES(fmi3GetInt32, , fmi3Int32)
NO_VARIABLES(fmi3GetUInt32, , fmi3UInt32)
NO_VARIABLES(fmi3GetInt64, , fmi3Int64)
NO_VARIABLES(fmi3GetUInt64, , fmi3UInt64)
NO_VARIABLES(fmi3GetBoolean, , fmi3Boolean)
NO_VARIABLES(fmi3GetString, , fmi3String)
NO_VARIABLES(fmi3SetFloat32, const, fmi3Float32)
NO_VARIABLES(fmi3SetInt8, const, fmi3Int8)
NO_VARIABLES(fmi3SetUInt8, const, fmi3UInt8)
NO_VARIABLES(fmi3SetInt16, const, fmi3Int16)
NO_VARIABLES(fmi3SetUInt16, const, fmi3UInt16)
NO_VARIABLES(fmi3SetInt32, const, fmi3Int32)
NO_VARIABLES(fmi3SetUInt32, const, fmi3UInt32)
NO_VARIABLES(fmi3SetInt64, const, fmi3Int64)
NO_VARIABLES(fmi3SetUInt64, const, fmi3UInt64)
NO_VARIABLES(fmi3SetBoolean, const, fmi3Boolean)
NO_VARIABLES(fmi3SetString, const, fmi3String)

#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif

"""
