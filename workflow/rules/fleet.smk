# Many sensors in one run: the sessions of a sample sheet (config `fleet.sessions`, a TSV of
# dataset, path, serial, date, operator) are datasets like any other; `snakemake --cores 2
# fleet` calibrates them and writes the fleet report: each parameter across units with the
# outliers flagged, each unit's drift between calibrations, and the calibration store
# (`imucal lookup results/fleet/store.json SERIAL DATE`). docs/fleet.md.


# reports/fleet.html is the fleet's page, not a dataset's lab report
ruleorder: fleet_report > report


rule fleet_report:
    input:
        unpack(fleet_calibrations),
    output:
        parameters="results/fleet/parameters.csv",
        summary="results/fleet/fleet.json",
        store="results/fleet/store.json",
        parameters_figure="results/fleet/parameters.png",
        drift_figure="results/fleet/drift.png",
        html="reports/fleet.html",
    log:
        "results/fleet/logs/fleet_report.log",
    conda:
        "../envs/imucal.yaml"
    params:
        sheet=config["fleet"]["sessions"],
        outlier_z=config["fleet"]["outlier_z"],
        drift_z=config["fleet"]["drift_z"],
        imucal_version=IMUCAL_VERSION,
    script:
        "../scripts/fleet_report.py"


rule fleet:
    input:
        "reports/fleet.html",
