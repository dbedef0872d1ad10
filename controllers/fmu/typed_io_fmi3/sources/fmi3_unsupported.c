/*
 * FMI 3.0 entry points that controllers/fmu/typed_io_fmi3 does not provide (ctmm).
 *
 * The standard requires every function to be exported; these report fmi3Error (or return NULL for
 * the model-exchange and scheduled-execution instantiation).  Compiled together with
 * typed_io_fmi3.c as listed in sources/buildDescription.xml.
 */
#include <stddef.h>

#include "fmi3Functions.h"


#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif

#define INSTANCE_UNSUPPORTED(name) { return fmi3Error; }
#define GET_SET(name, type, constness)                                                                    \
    fmi3Status name(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, \
                    constness type values[], size_t nValues) {                                             \
        if (nValueReferences == 0) return fmi3OK;                                                          \
        return fmi3Error;                                                                                  \
    }

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    return NULL; /* co-simulation only */
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    return NULL; /* co-simulation only */
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) INSTANCE_UNSUPPORTED(fmi3EnterEventMode)

GET_SET(fmi3GetInt8, fmi3Int8, )
GET_SET(fmi3GetInt16, fmi3Int16, )
GET_SET(fmi3GetUInt16, fmi3UInt16, )
GET_SET(fmi3GetUInt32, fmi3UInt32, )
GET_SET(fmi3GetInt64, fmi3Int64, )
GET_SET(fmi3GetUInt64, fmi3UInt64, )
GET_SET(fmi3GetString, fmi3String, )
GET_SET(fmi3SetInt8, fmi3Int8, const)
GET_SET(fmi3SetInt16, fmi3Int16, const)
GET_SET(fmi3SetUInt16, fmi3UInt16, const)
GET_SET(fmi3SetUInt32, fmi3UInt32, const)
GET_SET(fmi3SetInt64, fmi3Int64, const)
GET_SET(fmi3SetUInt64, fmi3UInt64, const)
GET_SET(fmi3SetString, fmi3String, const)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    if (nValueReferences == 0) return fmi3OK;
    return fmi3Error;
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    if (nValueReferences == 0) return fmi3OK;
    return fmi3Error;
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[]) INSTANCE_UNSUPPORTED(fmi3GetClock)

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[]) INSTANCE_UNSUPPORTED(fmi3SetClock)

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies) INSTANCE_UNSUPPORTED(fmi3GetNumberOfVariableDependencies)

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) INSTANCE_UNSUPPORTED(fmi3GetVariableDependencies)

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                      size_t *size) INSTANCE_UNSUPPORTED(fmi3SerializedFMUStateSize)

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) INSTANCE_UNSUPPORTED(fmi3SerializeFMUState)

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) INSTANCE_UNSUPPORTED(fmi3DeserializeFMUState)

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[],
                                        size_t nSensitivity) INSTANCE_UNSUPPORTED(fmi3GetDirectionalDerivative)

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[],
                                    size_t nSensitivity) INSTANCE_UNSUPPORTED(fmi3GetAdjointDerivative)

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) INSTANCE_UNSUPPORTED(fmi3EnterConfigurationMode)

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) INSTANCE_UNSUPPORTED(fmi3ExitConfigurationMode)

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[]) INSTANCE_UNSUPPORTED(fmi3GetIntervalDecimal)

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) INSTANCE_UNSUPPORTED(fmi3GetIntervalFraction)

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[]) INSTANCE_UNSUPPORTED(fmi3GetShiftDecimal)

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[],
                                fmi3UInt64 resolutions[]) INSTANCE_UNSUPPORTED(fmi3GetShiftFraction)

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences,
                                  const fmi3Float64 intervals[]) INSTANCE_UNSUPPORTED(fmi3SetIntervalDecimal)

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) INSTANCE_UNSUPPORTED(fmi3SetIntervalFraction)

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[]) INSTANCE_UNSUPPORTED(fmi3SetShiftDecimal)

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[]) INSTANCE_UNSUPPORTED(fmi3SetShiftFraction)

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) INSTANCE_UNSUPPORTED(fmi3EvaluateDiscreteStates)

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) INSTANCE_UNSUPPORTED(fmi3UpdateDiscreteStates)

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) INSTANCE_UNSUPPORTED(fmi3EnterContinuousTimeMode)

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation) INSTANCE_UNSUPPORTED(fmi3CompletedIntegratorStep)

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) INSTANCE_UNSUPPORTED(fmi3SetTime)

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) INSTANCE_UNSUPPORTED(fmi3SetContinuousStates)

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) INSTANCE_UNSUPPORTED(fmi3GetContinuousStateDerivatives)

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators) INSTANCE_UNSUPPORTED(fmi3GetEventIndicators)

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) INSTANCE_UNSUPPORTED(fmi3GetContinuousStates)

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) INSTANCE_UNSUPPORTED(fmi3GetNominalsOfContinuousStates)

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance,
                                          size_t *nEventIndicators) INSTANCE_UNSUPPORTED(fmi3GetNumberOfEventIndicators)

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance,
                                           size_t *nContinuousStates) INSTANCE_UNSUPPORTED(fmi3GetNumberOfContinuousStates)

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues) INSTANCE_UNSUPPORTED(fmi3GetOutputDerivatives)

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) INSTANCE_UNSUPPORTED(fmi3ActivateModelPartition)
