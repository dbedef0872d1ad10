/*
 * FMI 3.0 entry points that the ctmm FMUs do not support (ctmm): model-exchange and scheduled-execution
 * instantiation (NULL, with an error logged), binary variables, clocks, variable dependencies,
 * serialisation, directional and adjoint derivatives, configuration and event modes, intervals and
 * shifts, the model-exchange and scheduled-execution calls, output derivatives.
 *
 * One source shared by the shipped controller FMUs (controllers/fmu/pd_controller_fmi3, typed_io_fmi3:
 * a link in their sources/) and by every FMI 3.0 plant FMU that ctmm.export_fmu writes (copied into its
 * sources/).  The standard requires every function to be exported; these report through the FMU's own
 * logger, ctmm_fmi3_not_supported(instance, "<function>") defined in its main source, which returns
 * fmi3Error.
 */
#include <stddef.h>

#include "fmi3Functions.h"

#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wunused-parameter"
__attribute__((visibility("hidden")))   /* not an exported symbol of the FMU's binary */
#endif
fmi3Status ctmm_fmi3_not_supported(fmi3Instance instance, const char *function);

#define UNSUPPORTED(name) { return ctmm_fmi3_not_supported(instance, #name); }

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    if (logMessage != NULL) logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                                       "model exchange is not supported: this FMU is for co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    if (logMessage != NULL) logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                                       "scheduled execution is not supported: this FMU is for co-simulation only");
    return NULL;
}

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    return nValueReferences == 0 ? fmi3OK : ctmm_fmi3_not_supported(instance, "fmi3GetBinary (no Binary variables)");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    return nValueReferences == 0 ? fmi3OK : ctmm_fmi3_not_supported(instance, "fmi3SetBinary (no Binary variables)");
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[]) UNSUPPORTED(fmi3GetClock)

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[]) UNSUPPORTED(fmi3SetClock)

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies) UNSUPPORTED(fmi3GetNumberOfVariableDependencies)

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) UNSUPPORTED(fmi3GetVariableDependencies)

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                      size_t *size) UNSUPPORTED(fmi3SerializedFMUStateSize)

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) UNSUPPORTED(fmi3SerializeFMUState)

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) UNSUPPORTED(fmi3DeserializeFMUState)

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[],
                                        size_t nSensitivity) UNSUPPORTED(fmi3GetDirectionalDerivative)

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[],
                                    size_t nSensitivity) UNSUPPORTED(fmi3GetAdjointDerivative)

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) UNSUPPORTED(fmi3EnterConfigurationMode)

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) UNSUPPORTED(fmi3ExitConfigurationMode)

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[]) UNSUPPORTED(fmi3GetIntervalDecimal)

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) UNSUPPORTED(fmi3GetIntervalFraction)

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[]) UNSUPPORTED(fmi3GetShiftDecimal)

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[],
                                fmi3UInt64 resolutions[]) UNSUPPORTED(fmi3GetShiftFraction)

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences,
                                  const fmi3Float64 intervals[]) UNSUPPORTED(fmi3SetIntervalDecimal)

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) UNSUPPORTED(fmi3SetIntervalFraction)

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[]) UNSUPPORTED(fmi3SetShiftDecimal)

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[]) UNSUPPORTED(fmi3SetShiftFraction)

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) UNSUPPORTED(fmi3EvaluateDiscreteStates)

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) UNSUPPORTED(fmi3UpdateDiscreteStates)

fmi3Status fmi3EnterEventMode(fmi3Instance instance) UNSUPPORTED(fmi3EnterEventMode)

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) UNSUPPORTED(fmi3EnterContinuousTimeMode)

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation) UNSUPPORTED(fmi3CompletedIntegratorStep)

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) UNSUPPORTED(fmi3SetTime)

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) UNSUPPORTED(fmi3SetContinuousStates)

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) UNSUPPORTED(fmi3GetContinuousStateDerivatives)

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators) UNSUPPORTED(fmi3GetEventIndicators)

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) UNSUPPORTED(fmi3GetContinuousStates)

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) UNSUPPORTED(fmi3GetNominalsOfContinuousStates)

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance,
                                          size_t *nEventIndicators) UNSUPPORTED(fmi3GetNumberOfEventIndicators)

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance,
                                           size_t *nContinuousStates) UNSUPPORTED(fmi3GetNumberOfContinuousStates)

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues) UNSUPPORTED(fmi3GetOutputDerivatives)

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) UNSUPPORTED(fmi3ActivateModelPartition)
